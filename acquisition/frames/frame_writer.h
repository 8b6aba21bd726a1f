#pragma once
// Where grabbed frames go: a FrameSink. PngFolderWriter writes DIR/<prefix>NNNNNN.png (the
// interchange format's image files), atomically (temporary file, then rename: a reader never
// sees a partial PNG). Mono8/BayerRG8 -> 8-bit grey (Bayer raw, not demosaiced), Mono16 ->
// 16-bit grey, RGB8 -> 3-channel PNG.

#include <cstdint>
#include <filesystem>
#include <string>

#include "drivers/camera/camera.h"

namespace msmcal::frames {

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
