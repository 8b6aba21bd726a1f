#pragma once
// A colour camera's Bayer mosaic and its demosaicing, for tests: a BGR image as three measured
// channels becomes what a Bayer sensor measures (one colour per pixel) and OpenCV interpolates
// back (vision/dots.h, InterpolatedGreenParity).

#include <cstdint>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace msmcal::testing {

// Green is measured where (x + y) % 2 != interpolated_parity; the other pixels measure red on
// even rows and blue on odd rows (R G / G B at the origin for parity 0, G R / B G for 1).
inline cv::Mat BayerMosaic(const cv::Mat& bgr, int interpolated_parity) {
  cv::Mat raw(bgr.size(), CV_MAKETYPE(bgr.depth(), 1));
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x) {
      const int channel = (x + y) % 2 != interpolated_parity ? 1 : (y % 2 == 0 ? 2 : 0);
      if (bgr.depth() == CV_16U)
        raw.at<uint16_t>(y, x) = bgr.at<cv::Vec3w>(y, x)[channel];
      else
        raw.at<uint8_t>(y, x) = bgr.at<cv::Vec3b>(y, x)[channel];
    }
  return raw;
}

// OpenCV's bilinear or edge-aware demosaicing of BayerMosaic(.., interpolated_parity) (its
// codes name the pattern differently: R G / G B at the origin is "BayerBG"; the tests check the
// pair on a flat colour). Not VNG: OpenCV's VNG output is shifted by two pixels
// (opencv/opencv#5089, #27225), so it is no model of a camera.
inline cv::Mat Demosaic(const cv::Mat& raw, int interpolated_parity, bool edge_aware) {
  const int code = interpolated_parity == 0
                       ? (edge_aware ? cv::COLOR_BayerBG2BGR_EA : cv::COLOR_BayerBG2BGR)
                       : (edge_aware ? cv::COLOR_BayerGB2BGR_EA : cv::COLOR_BayerGB2BGR);
  cv::Mat out;
  cv::cvtColor(raw, out, code);
  return out;
}

}  // namespace msmcal::testing
