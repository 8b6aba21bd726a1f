#pragma once
// Writes an OpenCV image (8/16-bit, 1/3/4 channels, BGR order) into a mock camera frame buffer of
// width x height in `fmt`: converted (grey <-> RGB, 8 <-> 16 bit by a factor 256), placed at the
// top-left, cropped if larger, the rest black. Every byte of the buffer is written.

#include <cstdint>
#include <opencv2/core.hpp>

#include "mocks/camera/mock_gv_camera.h"

namespace msmcal::sim {

void PlaceImage(const cv::Mat& src, uint8_t* data, int width, int height, SimPixelFormat fmt);

}  // namespace msmcal::sim
