#include "drivers/camera/aravis_camera.h"

#include <arv.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <sstream>
#include <thread>
#include <utility>

namespace msmcal::camera {
namespace {

// RAII for GError: every Aravis call that reports errors gets a fresh one.
class GErrorHolder {
 public:
  GErrorHolder() = default;
  GErrorHolder(const GErrorHolder&) = delete;
  GErrorHolder& operator=(const GErrorHolder&) = delete;
  ~GErrorHolder() { g_clear_error(&error_); }
  GError** out() {
    g_clear_error(&error_);
    return &error_;
  }
  bool failed() const { return error_ != nullptr; }
  std::string message() const { return error_ ? error_->message : ""; }

 private:
  GError* error_ = nullptr;
};

int64_t SteadyNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

ArvPixelFormat ToArv(PixelFormat format) {
  switch (format) {
    case PixelFormat::kMono8:
      return ARV_PIXEL_FORMAT_MONO_8;
    case PixelFormat::kMono16:
      return ARV_PIXEL_FORMAT_MONO_16;
    case PixelFormat::kBayerRG8:
      return ARV_PIXEL_FORMAT_BAYER_RG_8;
    case PixelFormat::kRGB8:
      return ARV_PIXEL_FORMAT_RGB_8_PACKED;
  }
  return ARV_PIXEL_FORMAT_MONO_8;
}

std::optional<PixelFormat> FromArv(ArvPixelFormat format) {
  switch (format) {
    case ARV_PIXEL_FORMAT_MONO_8:
      return PixelFormat::kMono8;
    case ARV_PIXEL_FORMAT_MONO_16:
      return PixelFormat::kMono16;
    case ARV_PIXEL_FORMAT_BAYER_RG_8:
      return PixelFormat::kBayerRG8;
    case ARV_PIXEL_FORMAT_RGB_8_PACKED:
      return PixelFormat::kRGB8;
    default:
      return std::nullopt;
  }
}

// The stream's buffers. Frames hold a shared reference, so a frame released after Stop() or
// after the camera is gone frees its buffer instead of pushing it into a dead stream.
class AravisBufferPool : public FrameBufferOwner {
 public:
  explicit AravisBufferPool(ArvStream* stream) : stream_(stream) { g_object_ref(stream_); }
  ~AravisBufferPool() override { g_object_unref(stream_); }

  void Release(void* token) override {
    auto* buffer = static_cast<ArvBuffer*>(token);
    std::lock_guard<std::mutex> lock(mutex_);
    if (active_) {
      arv_stream_push_buffer(stream_, buffer);  // the stream takes the reference back
    } else {
      g_object_unref(buffer);
    }
  }
  void Deactivate() {
    std::lock_guard<std::mutex> lock(mutex_);
    active_ = false;
  }

 private:
  ArvStream* stream_;
  std::mutex mutex_;
  bool active_ = true;
};

struct ControlState {
  std::atomic<bool> lost{false};
};

void OnControlLost(ArvGvDevice* /*device*/, gpointer user_data) {
  static_cast<ControlState*>(user_data)->lost = true;
}

class AravisCamera : public Camera {
 public:
  AravisCamera(ArvCamera* camera, AravisCameraOptions options)
      : camera_(camera), options_(std::move(options)) {
    ArvDevice* device = arv_camera_get_device(camera_);
    if (ARV_IS_GV_DEVICE(device)) {
      control_lost_handler_ =
          g_signal_connect(device, "control-lost", G_CALLBACK(OnControlLost), &control_);
    }
    ReadInfo();
  }

  ~AravisCamera() override {
    Stop();
    if (control_lost_handler_ != 0) {
      g_signal_handler_disconnect(arv_camera_get_device(camera_), control_lost_handler_);
    }
    g_object_unref(camera_);
  }

  CameraInfo Info() const override { return info_; }

  Status Configure(const CameraConfig& config) override {
    if (std::string error = config.Validate(); !error.empty()) return Status::Error(error);
    if (stream_ != nullptr) return Status::Error("Configure: camera is streaming; Stop() first");
    GErrorHolder error;
    auto check = [&](const char* what) -> Status {
      if (!error.failed()) return Status::Ok();
      return Status::Error(options_.device + ": " + what + ": " + error.message());
    };
    arv_camera_set_acquisition_mode(camera_, ARV_ACQUISITION_MODE_CONTINUOUS, error.out());
    if (Status s = check("AcquisitionMode=Continuous"); !s) return s;
    arv_camera_set_pixel_format(camera_, ToArv(config.pixel_format), error.out());
    if (Status s =
            check(("PixelFormat=" + std::string(PixelFormatName(config.pixel_format))).c_str());
        !s) {
      return s;
    }
    const Roi& roi = config.roi;
    const int width = roi.width > 0 ? roi.width : info_.sensor_width - roi.x;
    const int height = roi.height > 0 ? roi.height : info_.sensor_height - roi.y;
    if (width <= 0 || height <= 0 || roi.x + width > info_.sensor_width ||
        roi.y + height > info_.sensor_height) {
      std::ostringstream out;
      out << options_.device << ": CameraConfig.roi = (" << roi.x << ", " << roi.y << ", "
          << roi.width << ", " << roi.height << ") does not fit the " << info_.sensor_width << "x"
          << info_.sensor_height << " sensor";
      return Status::Error(out.str());
    }
    // Offsets to 0 first so that any width fits, then size, then offsets.
    arv_camera_set_region(camera_, 0, 0, width, height, error.out());
    if (Status s = check("Width/Height"); !s) return s;
    if (roi.x != 0 || roi.y != 0) {
      arv_camera_set_region(camera_, roi.x, roi.y, width, height, error.out());
      if (Status s = check("OffsetX/OffsetY"); !s) return s;
    }
    if (config.exposure_us) {
      arv_camera_set_exposure_time(camera_, *config.exposure_us, error.out());
      if (Status s = check("ExposureTime"); !s) return s;
    }
    if (config.gain) {
      arv_camera_set_gain(camera_, *config.gain, error.out());
      if (Status s = check("Gain"); !s) return s;
    }
    if (config.frame_rate_hz) {
      arv_camera_set_frame_rate(camera_, *config.frame_rate_hz, error.out());
      if (Status s = check("AcquisitionFrameRate"); !s) return s;
    }
    switch (config.trigger) {
      case TriggerMode::kFreeRun:
        if (arv_camera_is_feature_available(camera_, "TriggerMode", nullptr)) {
          arv_camera_set_string(camera_, "TriggerMode", "Off", error.out());
          if (Status s = check("TriggerMode=Off"); !s) return s;
        }
        break;
      case TriggerMode::kSoftware:
        arv_camera_set_trigger(camera_, "Software", error.out());
        if (Status s = check("TriggerSource=Software"); !s) return s;
        break;
      case TriggerMode::kLine0:
        arv_camera_set_trigger(camera_, "Line0", error.out());
        if (Status s = check("TriggerSource=Line0"); !s) return s;
        break;
    }
    config_ = config;
    return Status::Ok();
  }

  Status Start() override {
    if (stream_ != nullptr) return Status::Ok();
    if (control_.lost) return Status::Error(options_.device + ": camera control lost");
    GErrorHolder error;
    const guint payload = arv_camera_get_payload(camera_, error.out());
    if (error.failed() || payload == 0) {
      return Status::Error(options_.device + ": PayloadSize: " + error.message());
    }
    ArvStream* stream = arv_camera_create_stream(camera_, nullptr, nullptr, error.out());
    if (stream == nullptr) {
      return Status::Error(options_.device + ": cannot create stream: " + error.message());
    }
    if (ARV_IS_GV_STREAM(stream)) {
      if (options_.auto_socket_buffer) {
        g_object_set(stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_AUTO, nullptr);
      }
      g_object_set(stream, "packet-resend",
                   options_.packet_resend ? ARV_GV_STREAM_PACKET_RESEND_ALWAYS
                                          : ARV_GV_STREAM_PACKET_RESEND_NEVER,
                   nullptr);
    }
    // The pool: allocated once per Start; buffers circulate between the stream and frames.
    for (int i = 0; i < config_.buffer_count; ++i) {
      arv_stream_push_buffer(stream, arv_buffer_new_allocate(payload));
    }
    stream_ = stream;
    pool_ = std::make_shared<AravisBufferPool>(stream_);
    unwrapper_.Reset();
    dropped_incomplete_ = 0;
    arv_camera_start_acquisition(camera_, error.out());
    if (error.failed()) {
      const std::string message = error.message();
      Stop();
      return Status::Error(options_.device + ": AcquisitionStart: " + message);
    }
    return Status::Ok();
  }

  void Stop() override {
    if (stream_ == nullptr) return;
    last_stats_ = StatsFromStream();
    arv_camera_stop_acquisition(camera_, nullptr);
    pool_->Deactivate();
    pool_.reset();
    g_object_unref(stream_);  // buffers still queued in the stream are freed with it
    stream_ = nullptr;
  }

  FrameResult NextFrame(int64_t timeout_us) override {
    FrameResult result;
    if (stream_ == nullptr) {
      result.status = FrameStatus::kNotStreaming;
      result.message = options_.device + ": not streaming";
      return result;
    }
    const int64_t deadline_ns = SteadyNowNs() + timeout_us * 1000;
    for (;;) {
      if (control_.lost) {
        result.status = FrameStatus::kDisconnected;
        result.message = options_.device + ": camera control lost (camera gone or unreachable)";
        return result;
      }
      const int64_t remaining_us = (deadline_ns - SteadyNowNs()) / 1000;
      if (remaining_us <= 0) break;
      // Wake at least every 200 ms to notice a lost camera.
      ArvBuffer* buffer = arv_stream_timeout_pop_buffer(
          stream_, static_cast<guint64>(std::min<int64_t>(remaining_us, 200000)));
      if (buffer == nullptr) continue;
      if (arv_buffer_get_status(buffer) != ARV_BUFFER_STATUS_SUCCESS ||
          arv_buffer_get_payload_type(buffer) != ARV_BUFFER_PAYLOAD_TYPE_IMAGE) {
        ++dropped_incomplete_;
        arv_stream_push_buffer(stream_, buffer);  // incomplete: counted, never handed out
        continue;
      }
      const auto format = FromArv(arv_buffer_get_image_pixel_format(buffer));
      size_t size = 0;
      const void* data = arv_buffer_get_image_data(buffer, &size);
      FrameInfo info;
      info.width = arv_buffer_get_image_width(buffer);
      info.height = arv_buffer_get_image_height(buffer);
      if (!format || data == nullptr ||
          size < static_cast<size_t>(info.width) * info.height * BytesPerPixel(*format)) {
        ++dropped_incomplete_;
        arv_stream_push_buffer(stream_, buffer);
        continue;
      }
      info.pixel_format = *format;
      info.device_timestamp_ns = static_cast<int64_t>(arv_buffer_get_timestamp(buffer));
      info.host_timestamp_ns = static_cast<int64_t>(arv_buffer_get_system_timestamp(buffer));
      info.frame_id = unwrapper_.Unwrap(arv_buffer_get_frame_id(buffer));
      result.status = FrameStatus::kOk;
      result.frame = Frame(info, static_cast<const uint8_t*>(data),
                           static_cast<size_t>(info.width) * info.height * BytesPerPixel(*format),
                           pool_, buffer);
      return result;
    }
    result.status = control_.lost ? FrameStatus::kDisconnected : FrameStatus::kTimeout;
    result.message = options_.device + (control_.lost ? ": camera control lost"
                                                      : ": no complete frame before the deadline");
    return result;
  }

  Status SoftwareTrigger() override {
    GErrorHolder error;
    arv_camera_software_trigger(camera_, error.out());
    if (error.failed())
      return Status::Error(options_.device + ": TriggerSoftware: " + error.message());
    return Status::Ok();
  }

  StreamStats Stats() const override { return stream_ ? StatsFromStream() : last_stats_; }

 private:
  void ReadInfo() {
    auto str = [&](const char* value) { return std::string(value ? value : ""); };
    info_.vendor = str(arv_camera_get_vendor_name(camera_, nullptr));
    info_.model = str(arv_camera_get_model_name(camera_, nullptr));
    info_.serial = str(arv_camera_get_device_serial_number(camera_, nullptr));
    arv_camera_get_sensor_size(camera_, &info_.sensor_width, &info_.sensor_height, nullptr);
    guint n = 0;
    gint64* formats = arv_camera_dup_available_pixel_formats(camera_, &n, nullptr);
    for (guint i = 0; i < n; ++i) {
      if (auto f = FromArv(static_cast<ArvPixelFormat>(formats[i])))
        info_.pixel_formats.push_back(*f);
    }
    g_free(formats);
  }

  StreamStats StatsFromStream() const {
    StreamStats stats;
    guint64 completed = 0, failures = 0, underruns = 0;
    arv_stream_get_statistics(stream_, &completed, &failures, &underruns);
    stats.completed = completed;
    stats.failed = failures + dropped_incomplete_;
    stats.underruns = underruns;
    if (ARV_IS_GV_STREAM(stream_)) {
      stats.missing_packets = arv_stream_get_info_uint64_by_name(stream_, "n_missing_packets");
      stats.resent_packets = arv_stream_get_info_uint64_by_name(stream_, "n_resent_packets");
    }
    stats.missing_frames = unwrapper_.skipped();
    return stats;
  }

  ArvCamera* camera_;
  AravisCameraOptions options_;
  CameraInfo info_;
  CameraConfig config_;
  ControlState control_;
  gulong control_lost_handler_ = 0;
  ArvStream* stream_ = nullptr;
  std::shared_ptr<AravisBufferPool> pool_;
  FrameIdUnwrapper unwrapper_{65535, 1};
  uint64_t dropped_incomplete_ = 0;
  StreamStats last_stats_;
};

}  // namespace

std::string AravisCameraOptions::Validate() const {
  std::ostringstream out;
  if (device.empty()) {
    out << "AravisCameraOptions.device is empty: give an IP address or an Aravis device id";
  } else if (packet_size != 0 && (packet_size < 576 || packet_size > 16384)) {
    out << "AravisCameraOptions.packet_size = " << packet_size << ": must be 0 or in [576, 16384]";
  } else if (control_wait_ms < 0 || control_wait_ms > 60000) {
    out << "AravisCameraOptions.control_wait_ms = " << control_wait_ms << ": must be in [0, 60000]";
  }
  return out.str();
}

OpenCameraResult OpenAravisCamera(const AravisCameraOptions& options) {
  OpenCameraResult result;
  if (std::string error = options.Validate(); !error.empty()) {
    result.error = error;
    return result;
  }
  GErrorHolder error;
  ArvCamera* camera = arv_camera_new(options.device.c_str(), error.out());
  if (camera == nullptr) {
    result.error = "camera '" + options.device + "' did not answer: " + error.message();
    return result;
  }
  if (arv_camera_is_gv_device(camera)) {
    // A client that died without leaving control (SIGKILL, a crash) holds it until its
    // heartbeat timeout (3 s by default) runs out; without control the camera ignores our
    // stream settings and streams to the dead client. Wait for it, then refuse.
    ArvGvDevice* gv = ARV_GV_DEVICE(arv_camera_get_device(camera));
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::milliseconds(options.control_wait_ms);
    while (!arv_gv_device_is_controller(gv)) {
      GErrorHolder take;
      if (arv_gv_device_take_control(gv, take.out())) break;
      if (std::chrono::steady_clock::now() >= deadline) {
        result.error = "camera '" + options.device +
                       "': control not granted within control_wait_ms = " +
                       std::to_string(options.control_wait_ms) +
                       " ms (another client holds it: a viewer, or a process killed less than a "
                       "heartbeat timeout ago)";
        g_object_unref(camera);
        return result;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    // An acquisition a dead client left running keeps streaming to its address (a camera reads
    // the stream destination when the acquisition starts): stop it, so that Start() begins a
    // stream to us. Harmless when stopped.
    GErrorHolder stop;
    arv_camera_stop_acquisition(camera, stop.out());
  }
  if (arv_camera_is_gv_device(camera) && options.packet_size > 0) {
    arv_camera_gv_set_packet_size(camera, options.packet_size, error.out());
    if (error.failed()) {
      result.error = "camera '" + options.device +
                     "': GevSCPSPacketSize=" + std::to_string(options.packet_size) + ": " +
                     error.message();
      g_object_unref(camera);
      return result;
    }
  }
  result.camera = std::make_unique<AravisCamera>(camera, options);
  return result;
}

}  // namespace msmcal::camera
