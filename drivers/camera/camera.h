#pragma once
// The narrow camera interface shared by every camera driver (GigE Vision through Aravis, V4L2)
// and the value types that travel with a frame. No vendor header appears here.
//
// Threading: a Camera is used from one thread (configure, start, NextFrame, stop). Frames may be
// moved to and released on any thread; releasing returns the frame's buffer to its driver's pool.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"

namespace msmcal::camera {

// Pixel formats the drivers hand out. Data is tightly packed row by row (stride = width * bytes
// per pixel); Mono16 is little-endian, RGB8 is R,G,B byte order.
enum class PixelFormat { kMono8, kMono16, kBayerRG8, kRGB8 };

int BytesPerPixel(PixelFormat format);
// GenICam PFNC names: "Mono8", "Mono16", "BayerRG8", "RGB8".
std::string_view PixelFormatName(PixelFormat format);
std::optional<PixelFormat> ParsePixelFormat(std::string_view name);

// A region of interest on the sensor, pixels. width/height 0 = the full sensor (from x, y).
struct Roi {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;
};

enum class TriggerMode { kFreeRun, kSoftware, kLine0 };

// What a driver is asked to do. Unset optionals leave the camera's current value alone.
struct CameraConfig {
  PixelFormat pixel_format = PixelFormat::kMono8;
  Roi roi;
  std::optional<double> exposure_us;    // > 0
  std::optional<double> gain;           // camera units (dB where the camera offers dB), >= 0
  std::optional<double> frame_rate_hz;  // > 0, free-run rate
  TriggerMode trigger = TriggerMode::kFreeRun;
  int buffer_count = 8;  // driver buffers in the pool, >= 2

  // Empty if valid, else "CameraConfig.<field> = <value>: <constraint>".
  std::string Validate() const;
};

struct CameraInfo {
  std::string vendor;
  std::string model;
  std::string serial;
  int sensor_width = 0;
  int sensor_height = 0;
  std::vector<PixelFormat> pixel_formats;  // formats this camera offers that we support
};

// Stream statistics since Start(). Incomplete frames are counted in `failed` and never handed
// out. `missing_frames` counts gaps in the device's frame ids / sequence numbers.
struct StreamStats {
  uint64_t completed = 0;
  uint64_t failed = 0;
  uint64_t missing_packets = 0;
  uint64_t resent_packets = 0;
  uint64_t underruns = 0;
  uint64_t missing_frames = 0;
};

// Result of an operation that can fail for expected reasons (device refused a value, device
// gone): the drivers' one result type (common/status.h).
using Status = common::Status;
using common::StatusCode;

struct FrameInfo {
  int width = 0;
  int height = 0;
  PixelFormat pixel_format = PixelFormat::kMono8;
  int64_t device_timestamp_ns = 0;  // the camera's clock (GigE: device ticks in ns)
  int64_t host_timestamp_ns = 0;    // host clock when the driver received the frame
  uint64_t frame_id = 0;            // device frame id unwrapped to 64 bits (monotonic)
};

// Where a frame's bytes come from and go back to. Implemented by each driver's buffer pool.
class FrameBufferOwner {
 public:
  virtual ~FrameBufferOwner() = default;
  // Called exactly once per handed-out frame, from any thread.
  virtual void Release(void* token) = 0;
};

// A frame: a view of a pooled buffer, move-only; destroying it returns the buffer to its pool.
// The pool outlives the camera if frames are still held (shared ownership), so releasing a frame
// after Stop() or after the camera is destroyed is safe (the buffer is then simply freed).
class Frame {
 public:
  Frame() = default;
  Frame(const FrameInfo& info, const uint8_t* data, size_t size_bytes,
        std::shared_ptr<FrameBufferOwner> owner, void* token)
      : info_(info),
        data_(data),
        size_bytes_(size_bytes),
        owner_(std::move(owner)),
        token_(token) {}
  // A frame that owns its bytes (tests, replay, decoded files).
  static Frame Owned(const FrameInfo& info, std::vector<uint8_t> bytes);

  Frame(Frame&& other) noexcept { *this = std::move(other); }
  Frame& operator=(Frame&& other) noexcept;
  Frame(const Frame&) = delete;
  Frame& operator=(const Frame&) = delete;
  ~Frame() { Reset(); }

  // Returns the buffer now (the frame becomes empty).
  void Reset();

  bool empty() const { return data_ == nullptr; }
  const FrameInfo& info() const { return info_; }
  const uint8_t* data() const { return data_; }
  size_t size_bytes() const { return size_bytes_; }
  size_t stride_bytes() const {
    return static_cast<size_t>(info_.width) * BytesPerPixel(info_.pixel_format);
  }

 private:
  FrameInfo info_;
  const uint8_t* data_ = nullptr;
  size_t size_bytes_ = 0;
  std::shared_ptr<FrameBufferOwner> owner_;
  void* token_ = nullptr;
};

enum class FrameStatus {
  kOk,            // frame holds a complete image
  kTimeout,       // no complete frame before the deadline (camera still there)
  kDisconnected,  // the camera is gone (unplugged, control lost); Stop() and reopen
  kNotStreaming,  // Start() was not called or failed
  kError,         // another device error, see message
};

std::string_view FrameStatusName(FrameStatus status);

struct FrameResult {
  FrameStatus status = FrameStatus::kError;
  Frame frame;
  std::string message;
};

class Camera {
 public:
  virtual ~Camera() = default;

  virtual CameraInfo Info() const = 0;
  // Applies `config` (validated first). Only while not streaming.
  virtual Status Configure(const CameraConfig& config) = 0;
  // Allocates the buffer pool (once per Start) and starts streaming.
  virtual Status Start() = 0;
  // Stops streaming; idempotent. Frames still held stay valid until released.
  virtual void Stop() = 0;
  // The next complete frame, waiting at most timeout_us. Never blocks longer.
  virtual FrameResult NextFrame(int64_t timeout_us) = 0;
  // One software trigger (TriggerMode::kSoftware).
  virtual Status SoftwareTrigger() = 0;
  virtual StreamStats Stats() const = 0;
};

struct OpenCameraResult {
  std::unique_ptr<Camera> camera;
  std::string error;  // set when camera is null: names the device and what failed
};

// Unwraps 16-bit GigE Vision block ids (1..65535, 0 is never used: 65535 is followed by 1) or
// 32-bit V4L2 sequence numbers to a monotonic 64-bit id and counts the ids skipped in between.
class FrameIdUnwrapper {
 public:
  // `period`: number of distinct ids before the wrap (65535 for GigE, 2^32 for V4L2);
  // `first_id`: the smallest id (1 for GigE, 0 for V4L2).
  FrameIdUnwrapper(uint64_t period, uint64_t first_id) : period_(period), first_id_(first_id) {}
  uint64_t Unwrap(uint64_t raw_id);
  uint64_t skipped() const { return skipped_; }
  void Reset() { started_ = false; }

 private:
  uint64_t period_;
  uint64_t first_id_;
  bool started_ = false;
  uint64_t last_raw_ = 0;
  uint64_t unwrapped_ = 0;
  uint64_t skipped_ = 0;
};

}  // namespace msmcal::camera
