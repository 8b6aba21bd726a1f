// Camera commands:
//   msmcal camera grab --device ADDRESS --count N --out DIR
//   msmcal camera calibrate --board COLSxROWS --square-mm S --out camera.yaml IMAGE...
//   msmcal mock camera --address 127.0.0.1 [--serial ID] [--scene pattern|replay:DIR|sim:CONFIG]
#include <signal.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "acquisition/frames/frame_grabber.h"
#include "acquisition/frames/frame_writer.h"
#include "app/command_registry.h"
#include "common/yaml_fields.h"
#include "drivers/camera/open_camera.h"
#include "mocks/camera/mock_gv_camera.h"
#include "mocks/camera/rig_scene_source.h"
#include "mocks/rig/sim_options.h"
#include "processing/calib/intrinsics.h"
#include "sessions/interchange/interchange_io.h"

namespace {

using msmcal::camera::CameraConfig;

struct GrabArgs {
  std::string device;
  uint64_t count = 1;
  std::string out;
  std::string pixel_format = "Mono8";
  int width = 0;
  int height = 0;
  double frame_rate_hz = 0;
  double exposure_us = 0;
  int64_t timeout_ms = 5000;
  uint64_t max_timeouts = 3;  // timed-out waits in a row before grab fails (0: never)
  int compression = 1;
};

void RunGrab(const GrabArgs& args) {
  // Checked before the camera is opened: values, and no earlier frames in --out.
  if (!std::isfinite(args.frame_rate_hz) || args.frame_rate_hz < 0)
    throw std::invalid_argument(
        "--frame-rate = " + msmcal::common::FieldNumber(args.frame_rate_hz) +
        ": must be >= 0 Hz (0 keeps the camera's)");
  if (!std::isfinite(args.exposure_us) || args.exposure_us < 0)
    throw std::invalid_argument("--exposure-us = " + msmcal::common::FieldNumber(args.exposure_us) +
                                ": must be >= 0 us (0 keeps the camera's)");
  if (std::filesystem::exists(args.out) &&
      !(std::filesystem::is_directory(args.out) && std::filesystem::is_empty(args.out)))
    throw std::runtime_error("--out " + args.out +
                             ": exists and is not an empty folder (camera grab does not "
                             "overwrite or mix with earlier frames)");
  auto opened = msmcal::camera::OpenCamera(args.device);
  if (!opened.camera) throw std::runtime_error(opened.error);
  msmcal::camera::Camera& camera = *opened.camera;
  const auto info = camera.Info();
  std::printf("camera %s %s (serial %s), sensor %dx%d\n", info.vendor.c_str(), info.model.c_str(),
              info.serial.c_str(), info.sensor_width, info.sensor_height);
  CameraConfig config;
  const auto format = msmcal::camera::ParsePixelFormat(args.pixel_format);
  if (!format) {
    throw std::runtime_error("--pixel-format '" + args.pixel_format +
                             "': must be Mono8, Mono16, BayerRG8 or RGB8");
  }
  config.pixel_format = *format;
  config.roi.width = args.width;
  config.roi.height = args.height;
  if (args.frame_rate_hz > 0) config.frame_rate_hz = args.frame_rate_hz;
  if (args.exposure_us > 0) config.exposure_us = args.exposure_us;
  // Storage may lag the camera for a while (PNG encoding of 10 MP frames): a queue of up to 16
  // frames, and enough driver buffers that the camera never starves meanwhile.
  const size_t queue = static_cast<size_t>(std::min<uint64_t>(args.count, 16));
  config.buffer_count = static_cast<int>(queue) + 4;
  if (auto s = camera.Configure(config); !s) throw std::runtime_error(s.message);
  msmcal::frames::PngWriterOptions writer_options;
  writer_options.dir = args.out;
  writer_options.png_compression = args.compression;
  msmcal::frames::PngFolderWriter writer(writer_options);
  msmcal::frames::GrabberOptions options;
  options.max_frames = args.count;
  options.frame_timeout_us = args.timeout_ms * 1000;
  options.max_consecutive_timeouts = args.max_timeouts;
  options.writer_threads = 2;
  options.queue_capacity = queue;
  msmcal::frames::FrameGrabber grabber(camera, writer, options);
  if (auto s = grabber.Start(); !s) throw std::runtime_error(s.message);
  // Live report once a second until capture and writing are done.
  std::mutex mutex;
  std::condition_variable cv;
  bool done = false;
  std::thread waiter([&] {
    grabber.Wait();
    std::lock_guard<std::mutex> lock(mutex);
    done = true;
    cv.notify_all();
  });
  {
    std::unique_lock<std::mutex> lock(mutex);
    while (!cv.wait_for(lock, std::chrono::seconds(1), [&] { return done; })) {
      const auto live = grabber.Stats();
      std::printf("  %llu/%llu written, %llu dropped, %.2f fps, %.1f MB/s\n",
                  static_cast<unsigned long long>(live.frames_written),
                  static_cast<unsigned long long>(args.count),
                  static_cast<unsigned long long>(live.frames_dropped), live.fps, live.mb_per_s);
      std::fflush(stdout);
    }
  }
  waiter.join();
  grabber.Stop();
  const auto stats = grabber.Stats();
  std::printf(
      "grabbed %llu, written %llu, dropped %llu, write errors %llu; %.2f fps, %.1f MB/s; "
      "camera: completed %llu, failed %llu, missing packets %llu, missing frames %llu\n",
      static_cast<unsigned long long>(stats.frames_grabbed),
      static_cast<unsigned long long>(stats.frames_written),
      static_cast<unsigned long long>(stats.frames_dropped),
      static_cast<unsigned long long>(stats.write_errors), stats.fps, stats.mb_per_s,
      static_cast<unsigned long long>(stats.camera.completed),
      static_cast<unsigned long long>(stats.camera.failed),
      static_cast<unsigned long long>(stats.camera.missing_packets),
      static_cast<unsigned long long>(stats.camera.missing_frames));
  if (stats.frames_written < args.count) {
    throw std::runtime_error("wrote " + std::to_string(stats.frames_written) + " of " +
                             std::to_string(args.count) + " frames to " + args.out +
                             (stats.last_error.empty() ? "" : ": " + stats.last_error));
  }
}

struct CalibrateArgs {
  std::string board = "9x6";
  double square_mm = 0;
  std::string out = "camera.yaml";
  std::vector<std::string> images;
};

void RunCalibrate(const CalibrateArgs& args) {
  const auto board = msmcal::calib::ParseBoardSize(args.board, args.square_mm);
  if (!board)
    throw std::runtime_error("--board '" + args.board + "': expected COLSxROWS, e.g. 9x6");
  if (std::string error = board->Validate(); !error.empty()) throw std::runtime_error(error);
  std::vector<std::vector<cv::Point2f>> views;
  std::vector<std::string> used, missing;
  cv::Size size;
  for (const std::string& file : args.images) {
    const cv::Mat image = cv::imread(file, cv::IMREAD_UNCHANGED);
    if (image.empty()) throw std::runtime_error(file + ": cannot read image");
    if (size.area() == 0) size = image.size();
    if (image.size() != size) {
      throw std::runtime_error(file + ": image size " + std::to_string(image.cols) + "x" +
                               std::to_string(image.rows) + " differs from the first image's " +
                               std::to_string(size.width) + "x" + std::to_string(size.height));
    }
    if (auto corners = msmcal::calib::DetectChessboard(image, *board)) {
      views.push_back(*corners);
      used.push_back(file);
    } else {
      missing.push_back(file);
    }
  }
  for (const std::string& file : missing) std::printf("board not found: %s\n", file.c_str());
  const auto result = msmcal::calib::CalibrateIntrinsics(views, *board, size);
  if (!result.ok) throw std::runtime_error("calibration failed: " + result.message);
  for (size_t i = 0; i < used.size(); ++i) {
    std::printf("view %s: %.4f px\n", used[i].c_str(), result.per_view_rms_px[i]);
  }
  const auto& c = result.camera;
  std::printf("views used %zu of %zu; RMS reprojection error %.4f px\n", used.size(),
              args.images.size(), result.rms_px);
  std::printf("fx %.3f fy %.3f cx %.3f cy %.3f; k1 %.5f k2 %.5f p1 %.5f p2 %.5f k3 %.5f\n", c.fx,
              c.fy, c.cx, c.cy, c.distortion[0], c.distortion[1], c.distortion[2], c.distortion[3],
              c.distortion[4]);
  msmcal::interchange::WriteCameraYaml(args.out, c);
  std::printf("wrote %s\n", args.out.c_str());
}

struct MockArgs {
  std::string address = "127.0.0.1";
  std::string serial = "MSMCAL-SIM-1";
  std::string scene = "pattern";
  int sensor_width = 3840;
  int sensor_height = 2748;
  double frame_rate_hz = 10;
  std::string fault;               // lost@N
  bool sensor_size_given = false;  // --sensor-width/--sensor-height on the command line
};

void RunMockCamera(const MockArgs& args) {
  msmcal::sim::FrameSource source;
  int sensor_width = args.sensor_width;
  int sensor_height = args.sensor_height;
  if (args.scene.rfind("sim:", 0) == 0) {
    // The simulated rig's frames at its camera's resolution (pixels match its camera model).
    if (args.sensor_size_given)
      throw CLI::ValidationError("--sensor-width/--sensor-height",
                                 "not with --scene sim: (the sensor is the simulator's camera's)");
    auto sim = std::make_shared<const msmcal::sim::RigSimulator>(
        msmcal::sim::LoadSimOptions(args.scene.substr(4)));
    sensor_width = sim->camera().width;
    sensor_height = sim->camera().height;
    source = msmcal::sim::MakeRigSceneSource(sim);
  } else if (args.scene == "pattern") {
    source = msmcal::sim::MakeTestPatternSource();
  } else if (args.scene.rfind("replay:", 0) == 0) {
    source = msmcal::sim::MakeReplaySource(msmcal::sim::ListPngFiles(args.scene.substr(7)));
  } else {
    throw std::runtime_error("--scene '" + args.scene +
                             "': expected pattern, replay:DIR or sim:CONFIG");
  }
  // Block the stop signals before any thread starts, then wait for one.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  msmcal::sim::MockGvCameraOptions options;
  options.address = args.address;
  options.serial = args.serial;
  options.sensor_width = sensor_width;
  options.sensor_height = sensor_height;
  options.frame_rate_hz = args.frame_rate_hz;
  if (!args.fault.empty()) {
    size_t used = 0;
    try {
      if (args.fault.rfind("lost@", 0) == 0)
        options.lost_after_frames = std::stoll(args.fault.substr(5), &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != args.fault.size() - 5 || options.lost_after_frames < 0)
      throw std::runtime_error("--fault '" + args.fault + "': expected lost@N, N >= 0");
  }
  std::string error;
  auto server = msmcal::sim::MockGvCamera::Start(options, source, &error);
  if (!server) throw std::runtime_error(error);
  if (!server->Answers()) {
    throw std::runtime_error("mock camera on " + args.address +
                             " does not answer (another GigE Vision server on this address?)");
  }
  std::printf("camera ready at %s\n", args.address.c_str());
  std::fflush(stdout);
  int received = 0;
  sigwait(&signals, &received);
  std::printf("stopping after %llu frames\n",
              static_cast<unsigned long long>(server->frames_served()));
}

void AddCameraCommands(CLI::App& app) {
  auto* camera =
      msmcal::app::GetOrAddSubcommand(app, "camera", "Camera acquisition and calibration");

  auto grab_args = std::make_shared<GrabArgs>();
  auto* grab = camera->add_subcommand("grab", "Save frames (PNG) from a camera");
  grab->add_option("--device", grab_args->device,
                   "GigE address (127.0.0.1), aravis:ID, or v4l2:/dev/videoN")
      ->required();
  grab->add_option("--count", grab_args->count, "Frames to save")->check(CLI::PositiveNumber);
  grab->add_option("--out", grab_args->out, "Output folder (created; or an empty one)")->required();
  grab->add_option("--pixel-format", grab_args->pixel_format, "Mono8|Mono16|BayerRG8|RGB8");
  grab->add_option("--width", grab_args->width, "ROI width (0 = sensor)");
  grab->add_option("--height", grab_args->height, "ROI height (0 = sensor)");
  grab->add_option("--frame-rate", grab_args->frame_rate_hz, "Frame rate, Hz (0 = keep)");
  grab->add_option("--exposure-us", grab_args->exposure_us, "Exposure, us (0 = keep)");
  grab->add_option("--timeout-ms", grab_args->timeout_ms,
                   "How long one wait for a frame lasts, ms (a timed-out wait is counted and "
                   "retried up to --max-timeouts times in a row)")
      ->check(CLI::Range(1, 3600000));
  grab->add_option("--max-timeouts", grab_args->max_timeouts,
                   "Timed-out waits in a row after which grab fails saying so (0 = wait for ever)")
      ->capture_default_str();
  grab->add_option("--png-compression", grab_args->compression, "0..9")->check(CLI::Range(0, 9));
  grab->callback([grab_args] { RunGrab(*grab_args); });

  auto cal_args = std::make_shared<CalibrateArgs>();
  auto* cal = camera->add_subcommand("calibrate", "Intrinsic calibration from chessboard images");
  cal->add_option("--board", cal_args->board, "Inner corners COLSxROWS, e.g. 9x6")->required();
  cal->add_option("--square-mm", cal_args->square_mm, "Square side, mm")->required();
  cal->add_option("--out", cal_args->out, "camera.yaml to write (interchange format)");
  cal->add_option("images", cal_args->images, "Chessboard images")->required();
  cal->callback([cal_args] { RunCalibrate(*cal_args); });

  auto* mock = msmcal::app::GetOrAddSubcommand(app, "mock", "Serve mock instruments");
  auto mock_args = std::make_shared<MockArgs>();
  auto* mock_camera = mock->add_subcommand("camera", "Serve a GigE Vision camera until stopped");
  mock_camera->add_option("--address", mock_args->address, "Address to serve on");
  mock_camera->add_option("--serial", mock_args->serial, "Serial number (max 15 characters)");
  mock_camera->add_option("--scene", mock_args->scene,
                          "pattern | replay:DIR (PNG files) | sim:CONFIG (rig simulator YAML)");
  const auto size_given = [mock_args](const std::string&) { mock_args->sensor_size_given = true; };
  mock_camera
      ->add_option("--sensor-width", mock_args->sensor_width,
                   "Sensor width, pixels (not with --scene sim:, whose camera sets it)")
      ->each(size_given);
  mock_camera
      ->add_option("--sensor-height", mock_args->sensor_height,
                   "Sensor height, pixels (not with --scene sim:, whose camera sets it)")
      ->each(size_given);
  mock_camera->add_option("--frame-rate", mock_args->frame_rate_hz, "Initial frame rate, Hz");
  mock_camera->add_option("--fault", mock_args->fault,
                          "lost@N: stop serving after N frames, as an unplugged camera "
                          "(off by default; docs/fault-campaign.md)");
  mock_camera->callback([mock_args] { RunMockCamera(*mock_args); });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/40, AddCameraCommands);
