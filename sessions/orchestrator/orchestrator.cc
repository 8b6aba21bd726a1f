#include "sessions/orchestrator/orchestrator.h"

#include <chrono>
#include <cstdio>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <stdexcept>

#include "acquisition/hall/hall_csv_writer.h"
#include "acquisition/hall/hall_recorder.h"
#include "drivers/camera/aravis_camera.h"
#include "drivers/generator/function_generator.h"
#include "drivers/generator/rig_generators.h"
#include "drivers/generator/safe_state.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::orchestrator {

namespace fs = std::filesystem;

std::string OrchestratorOptions::Validate() const {
  if (out_dir.empty()) return "OrchestratorOptions.out_dir is empty: a session folder is needed";
  if (camera_address.empty()) return "OrchestratorOptions.camera_address is empty";
  if (!(camera_frame_rate_hz > 0))
    return "OrchestratorOptions.camera_frame_rate_hz = " + std::to_string(camera_frame_rate_hz) +
           ": must be > 0";
  if (frame_timeout_ms <= 0)
    return "OrchestratorOptions.frame_timeout_ms = " + std::to_string(frame_timeout_ms) +
           ": must be > 0";
  if (max_stale_frames < 0)
    return "OrchestratorOptions.max_stale_frames = " + std::to_string(max_stale_frames) +
           ": must be >= 0";
  if (max_gate_attempts < 1)
    return "OrchestratorOptions.max_gate_attempts = " + std::to_string(max_gate_attempts) +
           ": must be >= 1";
  if (!(hall_max_seconds >= 0))
    return "OrchestratorOptions.hall_max_seconds = " + std::to_string(hall_max_seconds) +
           ": must be >= 0";
  if (std::string e = gate.Validate(); !e.empty()) return "OrchestratorOptions.gate: " + e;
  if (std::string e = generators.Validate(); !e.empty())
    return "OrchestratorOptions.generators: " + e;
  return {};
}

namespace {

std::string JoinLines(const std::vector<std::string>& lines) {
  std::string s = "rig check failed, not starting:";
  for (const auto& l : lines) s += "\n  - " + l;
  return s;
}

// Appends to session_log.txt (flushed per line) and echoes to the progress callback. Callable
// from the safe-state watcher thread.
class SessionLog {
 public:
  SessionLog(const fs::path& file, ProgressFn progress)
      : progress_(std::move(progress)), start_(std::chrono::steady_clock::now()) {
    file_ = std::fopen(file.string().c_str(), "a");
    if (!file_) throw std::runtime_error(file.string() + ": cannot open the session log");
  }
  ~SessionLog() {
    if (file_) std::fclose(file_);
  }
  void Line(const std::string& text) {
    std::lock_guard<std::mutex> lock(mu_);
    const double t =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    std::fprintf(file_, "[%8.3f s] %s\n", t, text.c_str());
    std::fflush(file_);
    if (progress_) progress_(text);
  }

 private:
  std::mutex mu_;
  std::FILE* file_ = nullptr;
  ProgressFn progress_;
  std::chrono::steady_clock::time_point start_;
};

cv::Mat FrameToMat(const camera::Frame& frame) {
  const auto& info = frame.info();
  int type = CV_8UC1;
  switch (info.pixel_format) {
    case camera::PixelFormat::kMono8:
    case camera::PixelFormat::kBayerRG8:
      type = CV_8UC1;
      break;
    case camera::PixelFormat::kMono16:
      type = CV_16UC1;
      break;
    case camera::PixelFormat::kRGB8:
      type = CV_8UC3;
      break;
  }
  cv::Mat view(info.height, info.width, type, const_cast<uint8_t*>(frame.data()),
               frame.stride_bytes());
  return view.clone();
}

int ExpectedDots(const dataset::Step1Frame& f) { return static_cast<int>(f.beams.size()); }
int ExpectedDots(const dataset::Step2Frame& f) {
  return static_cast<int>(f.beams.size() * std::max<size_t>(1, f.triggers.size()));
}

struct Instruments {
  std::unique_ptr<gen::FunctionGenerator> master, slave;
  std::unique_ptr<camera::Camera> cam;
  std::unique_ptr<hall_mcu::HallSensor> mcu;  // the background MCU link, checked
};

RigCheckResult CheckRig(const OrchestratorOptions& options, const dataset::Recording& plan,
                        RigOperator& rig_operator, Instruments* inst, std::string* mcu_device) {
  RigCheckResult r;
  // Generators: identity (on open), reference lock, signal design within limits.
  try {
    inst->master = gen::OpenKeysight33500(options.generators.unit1);
    r.found.push_back(options.generators.unit1.name + ": " + inst->master->Identify().model);
  } catch (const std::exception& e) {
    r.problems.push_back("generator 1 (" + options.generators.unit1.link.host + ":" +
                         std::to_string(options.generators.unit1.link.port) + "): " + e.what());
  }
  try {
    inst->slave = gen::OpenKeysight33500(options.generators.unit2);
    r.found.push_back(options.generators.unit2.name + ": " + inst->slave->Identify().model);
  } catch (const std::exception& e) {
    r.problems.push_back("generator 2 (" + options.generators.unit2.link.host + ":" +
                         std::to_string(options.generators.unit2.link.port) + "): " + e.what());
  }
  if (inst->master && inst->slave) {
    try {
      inst->master->Reset();
      inst->slave->Reset();
      inst->master->SetReference(gen::ReferenceSource::kInternal);
      inst->slave->SetReference(gen::ReferenceSource::kExternal);
      if (!inst->slave->ReferenceLocked())
        r.problems.push_back("generator 2 is not locked to generator 1's 10 MHz reference "
                             "(check the reference cable)");
      else
        r.found.push_back("generator 2 locked to the external 10 MHz reference");
    } catch (const std::exception& e) {
      r.problems.push_back(std::string("generator reference check: ") + e.what());
    }
  }
  try {
    (void)gen::PlanRigSignals(options.generators.signals);
  } catch (const std::exception& e) {
    r.problems.push_back(std::string("signal design: ") + e.what());
  }
  // Camera: opened by address, sensor size and pixel format.
  camera::OpenCameraResult opened =
      camera::OpenAravisCamera(camera::AravisCameraOptions{options.camera_address});
  if (!opened.camera) {
    r.problems.push_back("camera " + options.camera_address + ": " + opened.error);
  } else {
    inst->cam = std::move(opened.camera);
    const camera::CameraInfo info = inst->cam->Info();
    r.found.push_back("camera " + info.vendor + " " + info.model + " " + info.serial + " " +
                      std::to_string(info.sensor_width) + "x" +
                      std::to_string(info.sensor_height));
    if (info.sensor_width != plan.camera.width || info.sensor_height != plan.camera.height) {
      r.problems.push_back("camera sensor is " + std::to_string(info.sensor_width) + "x" +
                           std::to_string(info.sensor_height) + " but camera.yaml's is " +
                           std::to_string(plan.camera.width) + "x" +
                           std::to_string(plan.camera.height));
    }
    bool mono8 = false;
    for (auto f : info.pixel_formats) mono8 = mono8 || f == camera::PixelFormat::kMono8;
    if (!mono8) {
      r.problems.push_back("camera does not offer Mono8");
    } else {
      camera::CameraConfig config;
      config.pixel_format = camera::PixelFormat::kMono8;
      config.frame_rate_hz = options.camera_frame_rate_hz;
      config.buffer_count = 4;
      if (camera::Status s = inst->cam->Configure(config); !s)
        r.problems.push_back("camera configuration (Mono8, full sensor): " + s.message);
    }
  }
  // Hall MCU: identity and a status frame on the link.
  try {
    *mcu_device = rig_operator.PrepareHallRecording(HallRun::kBackground);
    hall_mcu::HallMcuOptions link = options.mcu;
    link.device = *mcu_device;
    inst->mcu = hall_mcu::OpenHallMcu(link);
    hall_mcu::DeviceInfo dev;
    if (auto c = inst->mcu->Identify(&dev); !c.ok) {
      r.problems.push_back("Hall MCU " + link.device + ": " + c.message);
    } else if (auto s = inst->mcu->RequestStatus(); !s.ok) {
      r.problems.push_back("Hall MCU " + link.device + ": no status: " + s.message);
    } else {
      r.found.push_back("Hall MCU " + link.device + ": " + dev.ToString());
    }
  } catch (const std::exception& e) {
    r.problems.push_back(std::string("Hall MCU: ") + e.what());
  }
  r.ok = r.problems.empty();
  return r;
}

// Records one Hall recording into hall/<name>.csv through the driver; returns the recorder's
// result. Throws when the recording ended abnormally.
acquisition::HallRecorderResult RecordHall(hall_mcu::HallSensor& sensor, const fs::path& csv,
                                           const OrchestratorOptions& options,
                                           const std::function<void()>& during) {
  acquisition::HallCsvWriter writer(csv);
  acquisition::HallRecorderOptions ro;
  ro.max_seconds = options.hall_max_seconds;
  ro.rate_hz = options.mcu_rate_hz;
  acquisition::HallRecorder recorder(
      sensor, [&writer](const hall_mcu::HallBatch& b) { writer.Write(b); }, ro);
  recorder.Start();
  std::exception_ptr error;
  try {
    if (during) during();
  } catch (...) {
    error = std::current_exception();
    recorder.Stop();
  }
  acquisition::HallRecorderResult result = recorder.Wait();
  writer.Close();
  if (error) std::rethrow_exception(error);
  if (result.end != acquisition::RecorderEnd::kEndOfData &&
      result.end != acquisition::RecorderEnd::kDuration &&
      result.end != acquisition::RecorderEnd::kStopped) {
    throw std::runtime_error(csv.filename().string() + ": Hall recording ended: " +
                             acquisition::ToString(result.end) + " " + result.message);
  }
  return result;
}

}  // namespace

RigCheckError::RigCheckError(const RigCheckResult& result)
    : std::runtime_error(JoinLines(result.problems)), result_(result) {}

SessionResult RunSession(const OrchestratorOptions& options, const dataset::Recording& plan,
                         RigOperator& rig_operator, const ProgressFn& progress) {
  if (std::string e = options.Validate(); !e.empty()) throw std::invalid_argument(e);
  const fs::path out = options.out_dir;
  if (fs::exists(out) && !fs::is_empty(out))
    throw std::runtime_error(out.string() + ": session folder exists and is not empty");
  fs::create_directories(out / "step1");
  fs::create_directories(out / "step2");
  fs::create_directories(out / "hall");
  SessionLog log(out / "session_log.txt", progress);
  SessionResult result;
  result.folder = out;
  log.Line("session " + out.string() + ": " + std::to_string(plan.step1.size()) +
           " step-1 frames, " + std::to_string(plan.step2.size()) + " step-2 frames, " +
           std::to_string(plan.triggers.size()) + " triggers");

  // Rig check.
  Instruments inst;
  std::string background_device;
  result.rig_check = CheckRig(options, plan, rig_operator, &inst, &background_device);
  for (const auto& f : result.rig_check.found) log.Line("rig check: " + f);
  if (!result.rig_check.ok) {
    for (const auto& p : result.rig_check.problems) log.Line("rig check PROBLEM: " + p);
    if (inst.master) inst.master->SafeState();
    if (inst.slave) inst.slave->SafeState();
    log.Line("refused to start; generator outputs off");
    throw RigCheckError(result.rig_check);
  }
  log.Line("rig check passed");

  // From here on outputs may be on: safe state on signal, exception and exit.
  gen::RigGenerators rig(*inst.master, *inst.slave);
  bool safe_done = false;
  auto safe_state = [&] {
    const bool ok = rig.SafeState();
    log.Line(ok ? "safe state: generator outputs off (confirmed)"
                : "safe state: outputs off NOT confirmed by both generators");
    safe_done = true;
    result.safe_state_confirmed = ok;
  };
  gen::SafeStateGuard guard(safe_state);
  int accepted_total = 0;
  std::vector<dataset::Step1Frame> step1_kept;
  std::vector<dataset::Step2Frame> step2_kept;
  try {
    rig.Apply(gen::PlanRigSignals(options.generators.signals));
    rig.VerifyLock();
    log.Line("generators: drive, laser trigger and clock applied, outputs on, locked");

    if (camera::Status s = inst.cam->Start(); !s)
      throw std::runtime_error("camera: start streaming: " + s.message);

    // Grabs a frame exposed after the current setup, runs the gate, writes the PNG.
    auto acquire = [&](const std::string& file, int step, int expected) -> FrameOutcome {
      FrameOutcome fo;
      fo.file = file;
      for (int attempt = 0; attempt < options.max_gate_attempts; ++attempt) {
        cv::Mat image;
        for (int stale = 0; image.empty(); ++stale) {
          if (stale > options.max_stale_frames)
            throw std::runtime_error(file + ": no frame of the current setup after " +
                                     std::to_string(stale) + " frames");
          camera::FrameResult fr =
              inst.cam->NextFrame(static_cast<int64_t>(options.frame_timeout_ms) * 1000);
          if (fr.status != camera::FrameStatus::kOk)
            throw std::runtime_error(file + ": camera: " +
                                     std::string(camera::FrameStatusName(fr.status)) + " " +
                                     fr.message);
          if (rig_operator.FrameShowsCurrentSetup(fr.frame.info())) image = FrameToMat(fr.frame);
        }
        GateResult g;
        g.accepted = true;
        if (options.run_quality_gate)
          g = CheckFrame(image, step, expected, plan.world_board, plan.sliding_board,
                         options.gate);
        if (g.accepted) {
          interchange::WriteImageAtomically(out / file, image);
          fo.accepted = true;
          fo.reason.clear();
          return fo;
        }
        fo.reason = g.reason;
      }
      return fo;
    };
    auto record = [&](FrameOutcome fo, size_t i, size_t n, const char* step) {
      log.Line(std::string(step) + ": frame " + std::to_string(i + 1) + "/" + std::to_string(n) +
               " " + fo.file + (fo.accepted ? " accepted" : " REJECTED: " + fo.reason));
      result.frames.push_back(fo);
      if (fo.accepted && options.fail_after_frames >= 0 &&
          ++accepted_total > options.fail_after_frames)
        throw std::runtime_error("injected failure after " + std::to_string(accepted_total) +
                                 " accepted frames (test hook)");
    };

    // Step 1: sliding plate poses, MSM not mounted.
    for (size_t i = 0; i < plan.step1.size(); ++i) {
      rig_operator.PrepareStep1Frame(i);
      FrameOutcome fo = acquire(plan.step1[i].file, 1, ExpectedDots(plan.step1[i]));
      if (fo.accepted) step1_kept.push_back(plan.step1[i]);
      record(fo, i, plan.step1.size(), "step 1");
    }

    // Background Hall recording (mirror top frame removed, coils driven).
    log.Line("Hall: background recording on " + background_device);
    {
      const auto r = RecordHall(*inst.mcu, out / "hall" / "background.csv", options, nullptr);
      result.background_readings = r.counts.readings_delivered;
      result.background_edges = r.counts.edges_delivered;
      log.Line("Hall: background " + std::to_string(r.counts.readings_delivered) +
               " readings, " + std::to_string(r.counts.edges_delivered) + " clock edges, " +
               std::to_string(r.counts.driver.readings_lost) + " lost (" +
               acquisition::ToString(r.end) + ")");
    }
    inst.mcu.reset();

    // Step 2 with the actual Hall recording running.
    const std::string actual_device = rig_operator.PrepareHallRecording(HallRun::kActual);
    hall_mcu::HallMcuOptions link = options.mcu;
    link.device = actual_device;
    auto actual_mcu = hall_mcu::OpenHallMcu(link);
    log.Line("Hall: actual recording on " + actual_device + " during step 2");
    const auto r = RecordHall(*actual_mcu, out / "hall" / "actual.csv", options, [&] {
      for (size_t i = 0; i < plan.step2.size(); ++i) {
        rig_operator.PrepareStep2Frame(i);
        FrameOutcome fo = acquire(plan.step2[i].file, 2, ExpectedDots(plan.step2[i]));
        if (fo.accepted) step2_kept.push_back(plan.step2[i]);
        record(fo, i, plan.step2.size(), "step 2");
      }
    });
    result.actual_readings = r.counts.readings_delivered;
    result.actual_edges = r.counts.edges_delivered;
    log.Line("Hall: actual " + std::to_string(r.counts.readings_delivered) + " readings, " +
             std::to_string(r.counts.edges_delivered) + " clock edges, " +
             std::to_string(r.counts.driver.readings_lost) + " lost (" +
             acquisition::ToString(r.end) + ")");
    inst.cam->Stop();
  } catch (const std::exception& e) {
    log.Line(std::string("ERROR: ") + e.what());
    if (inst.cam) inst.cam->Stop();
    safe_state();
    guard.Disarm();  // outputs are off already
    throw;
  }
  safe_state();
  guard.Disarm();

  // session.yaml last: a folder with a session.yaml is complete.
  dataset::Recording rec = plan;
  rec.hall_actual.reset();
  rec.hall_background.reset();
  rec.step1 = step1_kept;
  rec.step2 = step2_kept;
  if (std::string e = interchange::CheckRecording(rec); !e.empty())
    throw std::runtime_error("session after quality gates: " + e);
  interchange::WriteRecording(out, rec);
  (void)interchange::ReadRecording(out);  // reads back, Hall files included
  log.Line("session written: " + std::to_string(step1_kept.size()) + "/" +
           std::to_string(plan.step1.size()) + " step-1 and " +
           std::to_string(step2_kept.size()) + "/" + std::to_string(plan.step2.size()) +
           " step-2 frames accepted");
  (void)safe_done;
  return result;
}

}  // namespace msmcal::orchestrator
