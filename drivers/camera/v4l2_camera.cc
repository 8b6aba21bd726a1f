#include "drivers/camera/v4l2_camera.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/mman.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <sstream>
#include <vector>

namespace msmcal::camera {
namespace {

int64_t SteadyNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

uint32_t ToFourcc(PixelFormat format) {
  switch (format) {
    case PixelFormat::kMono8:
      return V4L2_PIX_FMT_GREY;
    case PixelFormat::kMono16:
      return V4L2_PIX_FMT_Y16;
    case PixelFormat::kBayerRG8:
      return V4L2_PIX_FMT_SRGGB8;
    case PixelFormat::kRGB8:
      return V4L2_PIX_FMT_RGB24;
  }
  return V4L2_PIX_FMT_GREY;
}

std::optional<PixelFormat> FromFourcc(uint32_t fourcc) {
  switch (fourcc) {
    case V4L2_PIX_FMT_GREY:
      return PixelFormat::kMono8;
    case V4L2_PIX_FMT_Y16:
      return PixelFormat::kMono16;
    case V4L2_PIX_FMT_SRGGB8:
      return PixelFormat::kBayerRG8;
    case V4L2_PIX_FMT_RGB24:
      return PixelFormat::kRGB8;
    default:
      return std::nullopt;
  }
}

std::string FourccText(uint32_t fourcc) {
  std::string text(4, ' ');
  for (int i = 0; i < 4; ++i) text[i] = static_cast<char>((fourcc >> (8 * i)) & 0xff);
  return text;
}

std::string ErrnoText(int err) { return std::string(std::strerror(err)); }

// mmap'd driver buffers. Frames share ownership: the mappings live until the last frame is
// released; a frame released after Stop() is not queued again.
class V4l2BufferPool : public FrameBufferOwner {
 public:
  struct Mapping {
    void* start = nullptr;
    size_t length = 0;
  };
  V4l2BufferPool(std::shared_ptr<V4l2Syscalls> sys, int fd) : sys_(std::move(sys)), fd_(fd) {}
  ~V4l2BufferPool() override {
    for (const Mapping& m : mappings_) {
      if (m.start != nullptr && m.start != MAP_FAILED) sys_->Munmap(m.start, m.length);
    }
  }

  void Release(void* token) override {
    const auto index = static_cast<uint32_t>(reinterpret_cast<uintptr_t>(token) - 1);
    std::lock_guard<std::mutex> lock(mutex_);
    if (!active_) return;
    Queue(index);
  }
  // Caller holds no lock (used while starting and from NextFrame for dropped buffers).
  int QueueUnlocked(uint32_t index) {
    std::lock_guard<std::mutex> lock(mutex_);
    return Queue(index);
  }
  void Deactivate() {
    std::lock_guard<std::mutex> lock(mutex_);
    active_ = false;
  }

  std::vector<Mapping> mappings_;

 private:
  int Queue(uint32_t index) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = index;
    return sys_->Ioctl(fd_, VIDIOC_QBUF, &buf);
  }

  std::shared_ptr<V4l2Syscalls> sys_;
  int fd_;
  std::mutex mutex_;
  bool active_ = true;
};

class V4l2Camera : public Camera {
 public:
  V4l2Camera(std::shared_ptr<V4l2Syscalls> sys, int fd, std::string path)
      : sys_(std::move(sys)), fd_(fd), path_(std::move(path)) {}

  ~V4l2Camera() override {
    Stop();
    sys_->Close(fd_);
  }

  Status ReadInfo() {
    v4l2_capability cap{};
    if (Xioctl(VIDIOC_QUERYCAP, &cap) < 0) return Errno("VIDIOC_QUERYCAP");
    const uint32_t caps =
        (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
    if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) {
      return Status::Error(path_ + ": not a video capture device (V4L2_CAP_VIDEO_CAPTURE unset)");
    }
    if (!(caps & V4L2_CAP_STREAMING)) {
      return Status::Error(path_ + ": no streaming I/O (V4L2_CAP_STREAMING unset)");
    }
    info_.vendor = reinterpret_cast<const char*>(cap.driver);
    info_.model = reinterpret_cast<const char*>(cap.card);
    info_.serial = reinterpret_cast<const char*>(cap.bus_info);
    for (uint32_t i = 0;; ++i) {
      v4l2_fmtdesc desc{};
      desc.index = i;
      desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      if (Xioctl(VIDIOC_ENUM_FMT, &desc) < 0) break;
      if (auto f = FromFourcc(desc.pixelformat)) {
        info_.pixel_formats.push_back(*f);
        // The largest frame size of any supported format is the "sensor".
        for (uint32_t j = 0;; ++j) {
          v4l2_frmsizeenum size{};
          size.index = j;
          size.pixel_format = desc.pixelformat;
          if (Xioctl(VIDIOC_ENUM_FRAMESIZES, &size) < 0) break;
          int w = 0, h = 0;
          if (size.type == V4L2_FRMSIZE_TYPE_DISCRETE) {
            w = static_cast<int>(size.discrete.width);
            h = static_cast<int>(size.discrete.height);
          } else {
            w = static_cast<int>(size.stepwise.max_width);
            h = static_cast<int>(size.stepwise.max_height);
          }
          if (static_cast<int64_t>(w) * h >
              static_cast<int64_t>(info_.sensor_width) * info_.sensor_height) {
            info_.sensor_width = w;
            info_.sensor_height = h;
          }
          if (size.type != V4L2_FRMSIZE_TYPE_DISCRETE) break;
        }
      }
    }
    if (info_.sensor_width == 0) {
      v4l2_format fmt{};
      fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      if (Xioctl(VIDIOC_G_FMT, &fmt) < 0) return Errno("VIDIOC_G_FMT");
      info_.sensor_width = static_cast<int>(fmt.fmt.pix.width);
      info_.sensor_height = static_cast<int>(fmt.fmt.pix.height);
    }
    return Status::Ok();
  }

  CameraInfo Info() const override { return info_; }

  Status Configure(const CameraConfig& config) override {
    if (std::string error = config.Validate(); !error.empty()) return Status::Error(error);
    if (pool_) return Status::Error(path_ + ": Configure while streaming; Stop() first");
    if (config.roi.x != 0 || config.roi.y != 0) {
      return Status::Error(path_ + ": CameraConfig.roi offset (" + std::to_string(config.roi.x) +
                           ", " + std::to_string(config.roi.y) +
                           ") is not supported by V4L2 capture: must be (0, 0)");
    }
    if (config.trigger != TriggerMode::kFreeRun) {
      return Status::Error(path_ + ": V4L2 has no standard trigger control: only free-run");
    }
    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    fmt.fmt.pix.width =
        static_cast<uint32_t>(config.roi.width > 0 ? config.roi.width : info_.sensor_width);
    fmt.fmt.pix.height =
        static_cast<uint32_t>(config.roi.height > 0 ? config.roi.height : info_.sensor_height);
    fmt.fmt.pix.pixelformat = ToFourcc(config.pixel_format);
    fmt.fmt.pix.field = V4L2_FIELD_NONE;
    if (Xioctl(VIDIOC_S_FMT, &fmt) < 0) return Errno("VIDIOC_S_FMT");
    if (fmt.fmt.pix.pixelformat != ToFourcc(config.pixel_format)) {
      return Status::Error(
          path_ + ": pixel format " + std::string(PixelFormatName(config.pixel_format)) +
          " not offered (device chose '" + FourccText(fmt.fmt.pix.pixelformat) + "')");
    }
    const uint32_t packed = fmt.fmt.pix.width * BytesPerPixel(config.pixel_format);
    if (fmt.fmt.pix.bytesperline != 0 && fmt.fmt.pix.bytesperline != packed) {
      return Status::Error(path_ + ": rows padded to " + std::to_string(fmt.fmt.pix.bytesperline) +
                           " bytes (packed " + std::to_string(packed) + "): not supported");
    }
    width_ = static_cast<int>(fmt.fmt.pix.width);
    height_ = static_cast<int>(fmt.fmt.pix.height);
    format_ = config.pixel_format;
    if (config.frame_rate_hz) {
      v4l2_streamparm parm{};
      parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      parm.parm.capture.timeperframe.numerator = 1000;
      parm.parm.capture.timeperframe.denominator =
          static_cast<uint32_t>(std::lround(*config.frame_rate_hz * 1000));
      if (Xioctl(VIDIOC_S_PARM, &parm) < 0) return Errno("VIDIOC_S_PARM (frame rate)");
    }
    if (config.exposure_us) {
      v4l2_control manual{V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL};
      Xioctl(VIDIOC_S_CTRL, &manual);  // absent on fixed-exposure devices: fine
      // V4L2_CID_EXPOSURE_ABSOLUTE is in units of 100 us.
      v4l2_control exposure{V4L2_CID_EXPOSURE_ABSOLUTE,
                            static_cast<int32_t>(std::lround(*config.exposure_us / 100.0))};
      if (Xioctl(VIDIOC_S_CTRL, &exposure) < 0) return Errno("VIDIOC_S_CTRL exposure");
    }
    if (config.gain) {
      v4l2_control gain{V4L2_CID_GAIN, static_cast<int32_t>(std::lround(*config.gain))};
      if (Xioctl(VIDIOC_S_CTRL, &gain) < 0) return Errno("VIDIOC_S_CTRL gain");
    }
    buffer_count_ = config.buffer_count;
    configured_ = true;
    return Status::Ok();
  }

  Status Start() override {
    if (lost_) return Status::Error(path_ + ": device gone (ENODEV)");
    if (pool_) return Status::Ok();
    if (!configured_) {
      CameraConfig defaults;
      if (!info_.pixel_formats.empty()) defaults.pixel_format = info_.pixel_formats.front();
      if (Status s = Configure(defaults); !s) return s;
    }
    v4l2_requestbuffers req{};
    req.count = static_cast<uint32_t>(buffer_count_);
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    if (Xioctl(VIDIOC_REQBUFS, &req) < 0) return Errno("VIDIOC_REQBUFS");
    if (req.count < 2) {
      return Status::Error(path_ + ": VIDIOC_REQBUFS gave " + std::to_string(req.count) +
                           " buffers, need >= 2");
    }
    auto pool = std::make_shared<V4l2BufferPool>(sys_, fd_);
    for (uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = i;
      if (Xioctl(VIDIOC_QUERYBUF, &buf) < 0) return FailStart(pool, "VIDIOC_QUERYBUF");
      void* start = sys_->Mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_,
                               static_cast<off_t>(buf.m.offset));
      if (start == MAP_FAILED) return FailStart(pool, "mmap");
      pool->mappings_.push_back({start, buf.length});
    }
    for (uint32_t i = 0; i < req.count; ++i) {
      if (pool->QueueUnlocked(i) < 0) return FailStart(pool, "VIDIOC_QBUF");
    }
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (Xioctl(VIDIOC_STREAMON, &type) < 0) return FailStart(pool, "VIDIOC_STREAMON");
    pool_ = std::move(pool);
    unwrapper_.Reset();
    stats_ = StreamStats{};
    return Status::Ok();
  }

  void Stop() override {
    if (!pool_) return;
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    Xioctl(VIDIOC_STREAMOFF, &type);
    pool_->Deactivate();
    const bool frames_outstanding = pool_.use_count() > 1;
    pool_.reset();  // unmaps now unless frames still hold the pool
    if (!frames_outstanding) {
      v4l2_requestbuffers req{};
      req.count = 0;
      req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      req.memory = V4L2_MEMORY_MMAP;
      Xioctl(VIDIOC_REQBUFS, &req);
    }
  }

  FrameResult NextFrame(int64_t timeout_us) override {
    FrameResult result;
    if (lost_) return Disconnected();
    if (!pool_) {
      result.status = FrameStatus::kNotStreaming;
      result.message = path_ + ": not streaming";
      return result;
    }
    const int64_t deadline_ns = SteadyNowNs() + timeout_us * 1000;
    for (;;) {
      const int64_t remaining_ns = deadline_ns - SteadyNowNs();
      if (remaining_ns <= 0) break;
      pollfd pfd{fd_, POLLIN, 0};
      const int timeout_ms = static_cast<int>((remaining_ns + 999999) / 1000000);
      const int n = sys_->Poll(&pfd, 1, timeout_ms);
      if (n < 0) {
        if (errno == EINTR) continue;
        result.status = FrameStatus::kError;
        result.message = path_ + ": poll: " + ErrnoText(errno);
        return result;
      }
      if (n == 0) break;
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      if (Xioctl(VIDIOC_DQBUF, &buf) < 0) {
        const int err = errno;
        if (err == EAGAIN) continue;
        if (err == ENODEV) {
          lost_ = true;
          return Disconnected();
        }
        if (err == EIO) {  // transient (signal loss); the kernel has requeued nothing we own
          ++stats_.failed;
          continue;
        }
        result.status = FrameStatus::kError;
        result.message = path_ + ": VIDIOC_DQBUF: " + ErrnoText(err);
        return result;
      }
      const size_t expected = static_cast<size_t>(width_) * height_ * BytesPerPixel(format_);
      const uint64_t id = unwrapper_.Unwrap(buf.sequence);
      if ((buf.flags & V4L2_BUF_FLAG_ERROR) || buf.bytesused < expected ||
          buf.index >= pool_->mappings_.size()) {
        ++stats_.failed;  // corrupt or short: counted, never handed out
        pool_->QueueUnlocked(buf.index);
        continue;
      }
      FrameInfo info;
      info.width = width_;
      info.height = height_;
      info.pixel_format = format_;
      info.device_timestamp_ns =
          static_cast<int64_t>(buf.timestamp.tv_sec) * 1000000000 + buf.timestamp.tv_usec * 1000;
      info.host_timestamp_ns = SteadyNowNs();
      info.frame_id = id;
      ++stats_.completed;
      result.status = FrameStatus::kOk;
      result.frame =
          Frame(info, static_cast<const uint8_t*>(pool_->mappings_[buf.index].start), expected,
                pool_, reinterpret_cast<void*>(static_cast<uintptr_t>(buf.index) + 1));
      return result;
    }
    result.status = FrameStatus::kTimeout;
    result.message = path_ + ": no complete frame before the deadline";
    return result;
  }

  Status SoftwareTrigger() override {
    return Status::Error(path_ + ": V4L2 has no software trigger");
  }

  StreamStats Stats() const override {
    StreamStats stats = stats_;
    stats.missing_frames = unwrapper_.skipped();
    return stats;
  }

 private:
  int Xioctl(unsigned long request, void* arg) {
    int r;
    do {
      r = sys_->Ioctl(fd_, request, arg);
    } while (r < 0 && errno == EINTR);
    if (r < 0 && errno == ENODEV) lost_ = true;
    return r;
  }
  Status Errno(const char* what) {
    const int err = errno;
    return Status::Error(path_ + ": " + what + ": " + ErrnoText(err));
  }
  Status FailStart(std::shared_ptr<V4l2BufferPool>& pool, const char* what) {
    Status status = Errno(what);
    pool->Deactivate();
    pool.reset();
    v4l2_requestbuffers req{};
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    Xioctl(VIDIOC_REQBUFS, &req);
    return status;
  }
  FrameResult Disconnected() {
    FrameResult result;
    result.status = FrameStatus::kDisconnected;
    result.message = path_ + ": device gone (ENODEV)";
    return result;
  }

  std::shared_ptr<V4l2Syscalls> sys_;
  int fd_;
  std::string path_;
  CameraInfo info_;
  bool configured_ = false;
  bool lost_ = false;
  int width_ = 0;
  int height_ = 0;
  PixelFormat format_ = PixelFormat::kMono8;
  int buffer_count_ = 8;
  std::shared_ptr<V4l2BufferPool> pool_;
  FrameIdUnwrapper unwrapper_{uint64_t{1} << 32, 0};
  StreamStats stats_;
};

}  // namespace

std::string V4l2CameraOptions::Validate() const {
  if (path.empty()) return "V4l2CameraOptions.path is empty: give a device node like /dev/video0";
  return "";
}

OpenCameraResult OpenV4l2Camera(const V4l2CameraOptions& options) {
  OpenCameraResult result;
  if (std::string error = options.Validate(); !error.empty()) {
    result.error = error;
    return result;
  }
  auto sys = options.syscalls ? options.syscalls : RealV4l2Syscalls();
  const int fd = sys->Open(options.path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    result.error = options.path + ": open: " + ErrnoText(errno);
    return result;
  }
  auto camera = std::make_unique<V4l2Camera>(sys, fd, options.path);
  if (Status s = camera->ReadInfo(); !s) {
    result.error = s.message;
    return result;  // camera's destructor closes fd
  }
  result.camera = std::move(camera);
  return result;
}

}  // namespace msmcal::camera
