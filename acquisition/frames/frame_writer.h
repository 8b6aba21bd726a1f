#pragma once
// Where grabbed frames go: a FrameSink. PngFolderWriter writes DIR/<prefix>NNNNNN.png (the
// interchange format's image files), atomically (temporary file, then rename: a reader never
// sees a partial PNG), as the image FrameImage gives: Mono8 -> 8-bit grey, Mono16 -> 16-bit
// grey, RGB8 and BayerRG8 -> 3-channel BGR.

#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

#include "drivers/camera/camera.h"

namespace msmcal::frames {

// A frame as the interchange format's image (1 channel mono or 3 channels BGR): Mono8 and
// Mono16 as a view of the frame's buffer (valid while the frame is), RGB8 converted to BGR,
// and BayerRG8 (R G / G B from the first pixel) demosaiced bilinearly into BGR. A Bayer raw
// written as grey would read as a mono image whose green spots are a checkerboard of measured
// and dark pixels; demosaiced, the solver sees the colour image it expects and recognises the
// interpolated half of its green (vision::InterpolatedGreenParity), where it fits no spot.
cv::Mat FrameImage(const camera::Frame& frame);

class FrameSink {
 public:
  virtual ~FrameSink() = default;
  // Stores frame number `index` (0, 1, ... in grab order). Thread-safe: the grabber may call it
  // from several writer threads. Returns bytes written, or an error naming the file.
  struct Result {
    bool ok = true;
    uint64_t bytes = 0;
    std::string message;
  };
  virtual Result Write(const camera::Frame& frame, uint64_t index) = 0;
};

struct PngWriterOptions {
  std::filesystem::path dir;
  std::string prefix;
  int png_compression = 1;  // 0 (none, fastest) .. 9 (smallest)
  bool fsync = false;       // fsync each file before the rename
  std::string Validate() const;
};

class PngFolderWriter : public FrameSink {
 public:
  // Creates the folder. Throws std::invalid_argument if options are invalid.
  explicit PngFolderWriter(PngWriterOptions options);
  Result Write(const camera::Frame& frame, uint64_t index) override;
  std::filesystem::path PathFor(uint64_t index) const;

 private:
  PngWriterOptions options_;
};

}  // namespace msmcal::frames
