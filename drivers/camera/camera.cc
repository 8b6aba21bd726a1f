#include "drivers/camera/camera.h"

#include <sstream>

namespace msmcal::camera {

int BytesPerPixel(PixelFormat format) {
  switch (format) {
    case PixelFormat::kMono8:
    case PixelFormat::kBayerRG8:
      return 1;
    case PixelFormat::kMono16:
      return 2;
    case PixelFormat::kRGB8:
      return 3;
  }
  return 1;
}

std::string_view PixelFormatName(PixelFormat format) {
  switch (format) {
    case PixelFormat::kMono8:
      return "Mono8";
    case PixelFormat::kMono16:
      return "Mono16";
    case PixelFormat::kBayerRG8:
      return "BayerRG8";
    case PixelFormat::kRGB8:
      return "RGB8";
  }
  return "?";
}

std::optional<PixelFormat> ParsePixelFormat(std::string_view name) {
  for (PixelFormat f :
       {PixelFormat::kMono8, PixelFormat::kMono16, PixelFormat::kBayerRG8, PixelFormat::kRGB8}) {
    if (PixelFormatName(f) == name) return f;
  }
  return std::nullopt;
}

std::string CameraConfig::Validate() const {
  std::ostringstream out;
  if (roi.x < 0 || roi.y < 0 || roi.width < 0 || roi.height < 0) {
    out << "CameraConfig.roi = (" << roi.x << ", " << roi.y << ", " << roi.width << ", "
        << roi.height << "): every field must be >= 0";
  } else if (exposure_us && !(*exposure_us > 0)) {
    out << "CameraConfig.exposure_us = " << *exposure_us << ": must be > 0";
  } else if (gain && !(*gain >= 0)) {
    out << "CameraConfig.gain = " << *gain << ": must be >= 0";
  } else if (frame_rate_hz && !(*frame_rate_hz > 0)) {
    out << "CameraConfig.frame_rate_hz = " << *frame_rate_hz << ": must be > 0";
  } else if (buffer_count < 2 || buffer_count > 256) {
    out << "CameraConfig.buffer_count = " << buffer_count << ": must be in [2, 256]";
  }
  return out.str();
}

namespace {
// Owns the bytes of Frame::Owned frames; the token is the heap vector.
class OwnedBytes : public FrameBufferOwner {
 public:
  void Release(void* token) override { delete static_cast<std::vector<uint8_t>*>(token); }
};
}  // namespace

Frame Frame::Owned(const FrameInfo& info, std::vector<uint8_t> bytes) {
  static const auto owner = std::make_shared<OwnedBytes>();
  auto* heap = new std::vector<uint8_t>(std::move(bytes));
  return Frame(info, heap->data(), heap->size(), owner, heap);
}

Frame& Frame::operator=(Frame&& other) noexcept {
  if (this != &other) {
    Reset();
    info_ = other.info_;
    data_ = other.data_;
    size_bytes_ = other.size_bytes_;
    owner_ = std::move(other.owner_);
    token_ = other.token_;
    other.data_ = nullptr;
    other.size_bytes_ = 0;
    other.token_ = nullptr;
  }
  return *this;
}

void Frame::Reset() {
  if (owner_) owner_->Release(token_);
  owner_.reset();
  data_ = nullptr;
  size_bytes_ = 0;
  token_ = nullptr;
}

std::string_view FrameStatusName(FrameStatus status) {
  switch (status) {
    case FrameStatus::kOk:
      return "ok";
    case FrameStatus::kTimeout:
      return "timeout";
    case FrameStatus::kDisconnected:
      return "disconnected";
    case FrameStatus::kNotStreaming:
      return "not streaming";
    case FrameStatus::kError:
      return "error";
  }
  return "?";
}

uint64_t FrameIdUnwrapper::Unwrap(uint64_t raw_id) {
  if (!started_) {
    started_ = true;
    last_raw_ = raw_id;
    unwrapped_ = raw_id;
    return unwrapped_;
  }
  // Forward distance from the last id on the ring [first_id, first_id + period).
  const uint64_t last = last_raw_ - first_id_;
  const uint64_t now = raw_id - first_id_;
  const uint64_t step = now >= last ? now - last : now + period_ - last;
  if (step == 0) return unwrapped_;  // repeated id: same frame
  if (step > 1) skipped_ += step - 1;
  unwrapped_ += step;
  last_raw_ = raw_id;
  return unwrapped_;
}

}  // namespace msmcal::camera
