#include "acquisition/frames/frame_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

namespace msmcal::frames {

std::string PngWriterOptions::Validate() const {
  if (dir.empty()) return "PngWriterOptions.dir is empty";
  if (png_compression < 0 || png_compression > 9) {
    return "PngWriterOptions.png_compression = " + std::to_string(png_compression) +
           ": must be in [0, 9]";
  }
  return "";
}

PngFolderWriter::PngFolderWriter(PngWriterOptions options) : options_(std::move(options)) {
  if (std::string error = options_.Validate(); !error.empty()) throw std::invalid_argument(error);
  std::filesystem::create_directories(options_.dir);
}

cv::Mat FrameImage(const camera::Frame& frame) {
  const camera::FrameInfo& info = frame.info();
  int type = CV_8UC1;
  if (info.pixel_format == camera::PixelFormat::kMono16) type = CV_16UC1;
  if (info.pixel_format == camera::PixelFormat::kRGB8) type = CV_8UC3;
  const cv::Mat view(info.height, info.width, type, const_cast<uint8_t*>(frame.data()),
                     frame.stride_bytes());
  cv::Mat out;
  switch (info.pixel_format) {
    case camera::PixelFormat::kMono8:
    case camera::PixelFormat::kMono16:
      return view;
    case camera::PixelFormat::kRGB8:
      cv::cvtColor(view, out, cv::COLOR_RGB2BGR);
      return out;
    case camera::PixelFormat::kBayerRG8:
      // OpenCV names a mosaic by its second row: GenICam's BayerRG (R G / G B) is "BayerBG".
      cv::cvtColor(view, out, cv::COLOR_BayerBG2BGR);
      return out;
  }
  return view;
}

std::filesystem::path PngFolderWriter::PathFor(uint64_t index) const {
  char name[32];
  std::snprintf(name, sizeof(name), "%06llu.png", static_cast<unsigned long long>(index));
  return options_.dir / (options_.prefix + name);
}

FrameSink::Result PngFolderWriter::Write(const camera::Frame& frame, uint64_t index) {
  Result result;
  const std::filesystem::path path = PathFor(index);
  // Mono: a view of the driver's buffer, no copy until the encoder reads it.
  const cv::Mat to_encode = FrameImage(frame);
  thread_local std::vector<uint8_t> encoded;
  encoded.clear();
  if (!cv::imencode(".png", to_encode, encoded,
                    {cv::IMWRITE_PNG_COMPRESSION, options_.png_compression,
                     cv::IMWRITE_PNG_STRATEGY, cv::IMWRITE_PNG_STRATEGY_RLE})) {
    result.ok = false;
    result.message = path.string() + ": PNG encoding failed";
    return result;
  }
  const std::string tmp = path.string() + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    result.ok = false;
    result.message = tmp + ": " + std::strerror(errno);
    return result;
  }
  size_t done = 0;
  while (done < encoded.size()) {
    const ssize_t n = ::write(fd, encoded.data() + done, encoded.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      result.ok = false;
      result.message = tmp + ": write: " + std::strerror(errno);
      ::close(fd);
      ::unlink(tmp.c_str());
      return result;
    }
    done += static_cast<size_t>(n);
  }
  if (options_.fsync) ::fsync(fd);
  ::close(fd);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    result.ok = false;
    result.message = path.string() + ": rename: " + std::strerror(errno);
    ::unlink(tmp.c_str());
    return result;
  }
  result.bytes = encoded.size();
  return result;
}

}  // namespace msmcal::frames
