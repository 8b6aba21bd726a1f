#include "mocks/camera/mock_gv_camera.h"

#include <arv.h>
#include <unistd.h>

#include <algorithm>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "mocks/camera/place_image.h"

namespace msmcal::sim {

int SimBytesPerPixel(SimPixelFormat format) {
  switch (format) {
    case SimPixelFormat::kMono8:
    case SimPixelFormat::kBayerRG8:
      return 1;
    case SimPixelFormat::kMono16:
      return 2;
    case SimPixelFormat::kRGB8:
      return 3;
  }
  return 1;
}

std::string MockGvCameraOptions::Validate() const {
  std::ostringstream out;
  if (address.empty()) {
    out << "MockGvCameraOptions.address is empty";
  } else if (serial.empty() || serial.size() >= 16) {
    out << "MockGvCameraOptions.serial = '" << serial << "': must have 1 to 15 characters";
  } else if (sensor_width < 16 || sensor_width > 16384 || sensor_height < 16 ||
             sensor_height > 16384) {
    out << "MockGvCameraOptions.sensor_width x sensor_height = " << sensor_width << "x"
        << sensor_height << ": each must be in [16, 16384]";
  } else if (width < 0 || height < 0 || width > sensor_width || height > sensor_height) {
    out << "MockGvCameraOptions.width x height = " << width << "x" << height
        << ": must be in [0, sensor size] (0 = sensor size)";
  } else if (!(frame_rate_hz >= 0.1 && frame_rate_hz <= 1000)) {
    out << "MockGvCameraOptions.frame_rate_hz = " << frame_rate_hz << ": must be in [0.1, 1000]";
  } else if (lost_after_frames < -1) {
    out << "MockGvCameraOptions.lost_after_frames = " << lost_after_frames
        << ": must be >= 0 (-1: no fault)";
  }
  return out.str();
}

struct MockGvCamera::Impl {
  ArvGvFakeCamera* server = nullptr;
  ArvFakeCamera* fake = nullptr;     // owned by server
  uint32_t initial_exposure_us = 0;  // the register when serving began
  std::string xml_path;
  // The lost_after_frames fault: the fill callback of the first frame past the limit (on the
  // server's only thread, which also answers GVCP) waits here until the camera is destroyed, so
  // neither that frame nor any control reply leaves: the camera falls silent at once, with no
  // second thread to race against the next frame.
  std::mutex mu;
  std::condition_variable cv;
  bool closing = false;

  void StopServer() {
    ArvGvFakeCamera* s = nullptr;
    {
      std::lock_guard lock(mu);
      std::swap(s, server);
    }
    if (s != nullptr) g_object_unref(s);  // joins the server thread
  }
};

namespace {
std::optional<SimPixelFormat> FromArv(uint32_t format) {
  switch (format) {
    case ARV_PIXEL_FORMAT_MONO_8:
      return SimPixelFormat::kMono8;
    case ARV_PIXEL_FORMAT_MONO_16:
      return SimPixelFormat::kMono16;
    case ARV_PIXEL_FORMAT_BAYER_RG_8:
      return SimPixelFormat::kBayerRG8;
    case ARV_PIXEL_FORMAT_RGB_8_PACKED:
      return SimPixelFormat::kRGB8;
    default:
      return std::nullopt;
  }
}
}  // namespace

void MockGvCamera::Fill(void* buffer_ptr, void* self_ptr, uint32_t /*exposure_us*/,
                        uint32_t /*gain*/, uint32_t pixel_format) {
  auto* buffer = static_cast<ArvBuffer*>(buffer_ptr);
  auto* self = static_cast<MockGvCamera*>(self_ptr);
  if (buffer == nullptr) return;
  // arv_buffer_get_data reports size 0 here (Aravis issue #955): size from the registers.
  guint32 width = 0, height = 0;
  arv_fake_camera_read_register(self->impl_->fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, &width);
  arv_fake_camera_read_register(self->impl_->fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, &height);
  auto* data = static_cast<uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, nullptr)));
  if (data == nullptr) return;
  const uint64_t index = self->frames_served_.load();
  const int64_t lost_after = self->options_.lost_after_frames;
  if (lost_after >= 0 && index >= static_cast<uint64_t>(lost_after)) {
    self->lost_.store(true);
    std::unique_lock lock(self->impl_->mu);
    self->impl_->cv.wait(lock, [&] { return self->impl_->closing; });
    return;  // the destructor has set every packet of this frame to be dropped
  }
  const auto format = FromArv(pixel_format);
  if (!format) {
    std::memset(
        data, 0,
        static_cast<size_t>(width) * height * (ARV_PIXEL_FORMAT_BIT_PER_PIXEL(pixel_format) / 8));
  } else {
    self->source_(data, static_cast<int>(width), static_cast<int>(height), *format,
                  static_cast<int64_t>(arv_buffer_get_timestamp(buffer)), index);
  }
  self->frames_served_.store(index + 1);
}

std::optional<double> MockGvCamera::ClientExposureUs() const {
  if (!impl_ || !impl_->fake) return std::nullopt;
  guint32 v = 0;
  arv_fake_camera_read_register(impl_->fake, ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US, &v);
  if (v == impl_->initial_exposure_us || v == 0) return std::nullopt;
  return static_cast<double>(v);
}

std::unique_ptr<MockGvCamera> MockGvCamera::Start(const MockGvCameraOptions& options,
                                                  FrameSource source, std::string* error) {
  if (std::string message = options.Validate(); !message.empty()) {
    if (error) *error = message;
    return nullptr;
  }
  std::unique_ptr<MockGvCamera> camera(new MockGvCamera());
  camera->options_ = options;
  camera->source_ = source ? std::move(source) : MakeTestPatternSource();
  camera->impl_ = std::make_unique<Impl>();
  Impl& impl = *camera->impl_;

  // The fake camera reads its GenICam XML from a file.
  std::string path = (std::filesystem::temp_directory_path() / "msmcal-gv-XXXXXX.xml").string();
  const int fd = ::mkstemps(path.data(), 4);
  if (fd < 0) {
    if (error) *error = "cannot create the GenICam XML file in " + path;
    return nullptr;
  }
  const std::string xml = GenicamXml();
  const bool written = ::write(fd, xml.data(), xml.size()) == static_cast<ssize_t>(xml.size());
  ::close(fd);
  impl.xml_path = path;
  if (!written) {
    if (error) *error = "cannot write " + path;
    std::remove(path.c_str());
    return nullptr;
  }
  impl.server = arv_gv_fake_camera_new_full(options.address.c_str(), options.serial.c_str(),
                                            impl.xml_path.c_str());
  if (impl.server == nullptr || !arv_gv_fake_camera_is_running(impl.server)) {
    if (error) *error = "cannot serve a GigE Vision camera on '" + options.address + "'";
    return nullptr;  // destructor cleans up
  }
  impl.fake = arv_gv_fake_camera_get_fake_camera(impl.server);
  arv_fake_camera_read_register(impl.fake, ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US,
                                &impl.initial_exposure_us);
  const int width = options.width > 0 ? options.width : options.sensor_width;
  const int height = options.height > 0 ? options.height : options.sensor_height;
  arv_fake_camera_write_register(impl.fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH,
                                 static_cast<guint32>(options.sensor_width));
  arv_fake_camera_write_register(impl.fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT,
                                 static_cast<guint32>(options.sensor_height));
  arv_fake_camera_write_register(impl.fake, ARV_FAKE_CAMERA_REGISTER_WIDTH,
                                 static_cast<guint32>(width));
  arv_fake_camera_write_register(impl.fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT,
                                 static_cast<guint32>(height));
  arv_fake_camera_write_register(impl.fake, ARV_FAKE_CAMERA_REGISTER_ACQUISITION_FRAME_PERIOD_US,
                                 static_cast<guint32>(1e6 / options.frame_rate_hz));
  // GigE Vision bootstrap registers (GVBS): manufacturer name 0x48, model name 0x68, 32 bytes.
  auto write_string = [&](guint32 address, const char* text) {
    char field[32] = {};
    std::strncpy(field, text, sizeof(field) - 1);
    arv_fake_camera_write_memory(impl.fake, address, sizeof(field), field);
  };
  write_string(0x48, "msmcal");
  write_string(0x68, "MSMCAL-SIM");
  arv_fake_camera_set_fill_pattern(
      impl.fake,
      reinterpret_cast<ArvFakeCameraFillPattern>(
          +[](ArvBuffer* buffer, void* data, guint32 exposure, guint32 gain, ArvPixelFormat fmt) {
            Fill(buffer, data, exposure, gain, fmt);
          }),
      camera.get());
  return camera;
}

MockGvCamera::~MockGvCamera() {
  if (impl_) {
    // A server held by the lost fault sends nothing more: its pending frame's packets are all
    // dropped ("gvsp-lost-ratio" 1) before its fill callback is released.
    if (lost_.load() && impl_->server != nullptr)
      g_object_set(impl_->server, "gvsp-lost-ratio", 1.0, nullptr);
    {
      std::lock_guard lock(impl_->mu);
      impl_->closing = true;
    }
    impl_->cv.notify_all();
    impl_->StopServer();
    if (!impl_->xml_path.empty()) std::remove(impl_->xml_path.c_str());
  }
}

bool MockGvCamera::Answers() const {
  GError* error = nullptr;
  ArvCamera* client = arv_camera_new(options_.address.c_str(), &error);
  g_clear_error(&error);
  if (client == nullptr) return false;
  g_object_unref(client);
  return true;
}

uint8_t PatternByte(uint64_t frame_index, size_t i) {
  if (i < 8) return static_cast<uint8_t>(frame_index >> (8 * i));
  return static_cast<uint8_t>(((i % 4099) * 7 + frame_index * 13) & 0xff);
}

FrameSource MakeTestPatternSource() {
  return [](uint8_t* data, int width, int height, SimPixelFormat fmt, int64_t /*timestamp_ns*/,
            uint64_t frame_index) {
    const size_t size = static_cast<size_t>(width) * height * SimBytesPerPixel(fmt);
    // The pattern repeats every kPeriod bytes: build one period, copy it, then write the header.
    constexpr size_t kPeriod = 4099;
    uint8_t period[kPeriod];
    const auto offset = static_cast<uint8_t>(frame_index * 13);
    for (size_t k = 0; k < kPeriod; ++k) period[k] = static_cast<uint8_t>(k * 7 + offset);
    for (size_t i = 0; i < size; i += kPeriod) {
      std::memcpy(data + i, period, std::min(kPeriod, size - i));
    }
    for (size_t i = 0; i < std::min<size_t>(8, size); ++i) data[i] = PatternByte(frame_index, i);
  };
}

std::vector<std::filesystem::path> ListPngFiles(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> files;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    if (entry.is_regular_file() && entry.path().extension() == ".png") {
      files.push_back(entry.path());
    }
  }
  if (ec) throw std::runtime_error(dir.string() + ": cannot list: " + ec.message());
  if (files.empty()) throw std::runtime_error(dir.string() + ": no *.png files to replay");
  std::sort(files.begin(), files.end());
  return files;
}

FrameSource MakeReplaySource(const std::vector<std::filesystem::path>& files) {
  if (files.empty()) throw std::runtime_error("replay source: no image files given");
  auto images = std::make_shared<std::vector<cv::Mat>>();
  for (const auto& file : files) {
    cv::Mat image = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
    if (image.empty()) throw std::runtime_error(file.string() + ": cannot decode image");
    images->push_back(image);
  }
  return [images](uint8_t* data, int width, int height, SimPixelFormat fmt,
                  int64_t /*timestamp_ns*/, uint64_t frame_index) {
    PlaceImage((*images)[frame_index % images->size()], data, width, height, fmt);
  };
}

void PlaceImage(const cv::Mat& src, uint8_t* data, int width, int height, SimPixelFormat fmt) {
  int type = CV_8UC1;
  if (fmt == SimPixelFormat::kMono16) type = CV_16UC1;
  if (fmt == SimPixelFormat::kRGB8) type = CV_8UC3;
  cv::Mat out(height, width, type, data);
  out.setTo(0);
  cv::Mat converted;
  if (fmt == SimPixelFormat::kRGB8) {
    if (src.channels() == 1) {
      cv::cvtColor(src, converted, cv::COLOR_GRAY2RGB);
    } else {
      cv::cvtColor(src, converted, src.channels() == 4 ? cv::COLOR_BGRA2RGB : cv::COLOR_BGR2RGB);
    }
  } else if (src.channels() == 1) {
    converted = src;
  } else {
    cv::cvtColor(src, converted, src.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  }
  if (fmt == SimPixelFormat::kMono16 && converted.depth() == CV_8U) {
    converted.convertTo(converted, CV_16U, 256.0);
  } else if (fmt != SimPixelFormat::kMono16 && converted.depth() == CV_16U) {
    converted.convertTo(converted, CV_8U, 1.0 / 256.0);
  }
  const int w = std::min(width, converted.cols);
  const int h = std::min(height, converted.rows);
  converted(cv::Rect(0, 0, w, h)).copyTo(out(cv::Rect(0, 0, w, h)));
}

}  // namespace msmcal::sim
