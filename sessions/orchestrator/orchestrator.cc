#include "sessions/orchestrator/orchestrator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
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
#include "processing/signal/rig_signals.h"
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
  if (!(background_seconds >= 0))
    return "OrchestratorOptions.background_seconds = " + std::to_string(background_seconds) +
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
    {
      std::lock_guard<std::mutex> lock(mu_);
      const double t =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
      std::fprintf(file_, "[%8.3f s] %s\n", t, text.c_str());
      std::fflush(file_);
    }
    // Outside the lock: the safe-state watcher may log while the callback runs.
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

RigCheckResult CheckRig(const OrchestratorOptions& options, const dataset::Recording* plan,
                        const std::string& mcu_device, Instruments* inst) {
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
        r.problems.push_back(
            "generator 2 is not locked to generator 1's 10 MHz reference "
            "(check the reference cable)");
      else
        r.found.push_back("generator 2 locked to the external 10 MHz reference");
    } catch (const std::exception& e) {
      r.problems.push_back(std::string("generator reference check: ") + e.what());
    }
  }
  try {
    if (plan)
      (void)PlanSessionSignals(options.generators.signals, *plan);
    else
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
                      std::to_string(info.sensor_width) + "x" + std::to_string(info.sensor_height));
    if (plan &&
        (info.sensor_width != plan->camera.width || info.sensor_height != plan->camera.height)) {
      r.problems.push_back("camera sensor is " + std::to_string(info.sensor_width) + "x" +
                           std::to_string(info.sensor_height) + " but camera.yaml's is " +
                           std::to_string(plan->camera.width) + "x" +
                           std::to_string(plan->camera.height));
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
    hall_mcu::HallMcuOptions link = options.mcu;
    link.device = mcu_device;
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
// With `during`, the recording runs while it does and is stopped when it returns; without, it
// runs for max_seconds of MCU time (or to the end of the MCU's data).
acquisition::HallRecorderResult RecordHall(hall_mcu::HallSensor& sensor, const fs::path& csv,
                                           const OrchestratorOptions& options, double max_seconds,
                                           const std::function<void()>& during) {
  acquisition::HallCsvWriter writer(csv);
  acquisition::HallRecorderOptions ro;
  ro.max_seconds = max_seconds;
  ro.rate_hz = options.mcu_rate_hz;
  acquisition::HallRecorder recorder(
      sensor, [&writer](const hall_mcu::HallBatch& b) { writer.Write(b); }, ro);
  recorder.Start();
  std::exception_ptr error;
  try {
    if (during) {
      during();
      recorder.Stop();
    }
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

gen::RigSignalPlan PlanSessionSignals(const gen::RigSignalsConfig& config,
                                      const dataset::Recording& plan) {
  gen::RigSignalPlan p = gen::PlanRigSignals(config);
  const double period = p.trigger.pattern_period_s;
  if (plan.drive.pattern_period_s > 0 &&
      std::abs(plan.drive.pattern_period_s - period) > 1e-9 * period) {
    throw std::invalid_argument(
        "session plan: drive.pattern_period_s = " + std::to_string(plan.drive.pattern_period_s) +
        " but the configured drives give " + std::to_string(period));
  }
  signal::TriggerDesign d;
  d.pattern_period_s = period;
  d.arb = signal::ChooseArbTiming(period, config.trigger);
  const double rate = d.arb.sample_rate_sps;
  d.pulse_samples = std::max<int64_t>(
      1, static_cast<int64_t>(std::ceil(config.trigger.pulse_width_s * rate - 1e-9)));
  for (const auto& t : plan.triggers) {
    if (!(t.t_s >= 0 && t.t_s < period))
      throw std::invalid_argument("session plan: triggers[" + std::to_string(t.j) +
                                  "].t_s = " + std::to_string(t.t_s) + ": outside [0, " +
                                  std::to_string(period) + ")");
    const int64_t index = std::llround(t.t_s * rate) % d.arb.points;
    d.ideal_times_s.push_back(t.t_s);
    d.sample_index.push_back(index);
    d.times_s.push_back(static_cast<double>(index) / rate);
    d.max_quantisation_error_s =
        std::max(d.max_quantisation_error_s, std::abs(d.times_s.back() - t.t_s));
  }
  d.duty = static_cast<double>(d.pulse_samples * static_cast<int64_t>(plan.triggers.size())) /
           static_cast<double>(d.arb.points);
  if (d.duty > config.trigger.max_duty)
    throw std::invalid_argument("session plan: laser duty " + std::to_string(d.duty) +
                                " exceeds trigger.max_duty " +
                                std::to_string(config.trigger.max_duty));
  p.trigger = d;
  p.unit2_ch1.arb_samples = signal::TriggerArbSamples(d);
  p.unit2_ch1.arb_sample_rate_sps = rate;
  return p;
}

RigCheckResult CheckRigOnly(const OrchestratorOptions& options, const dataset::Recording* plan,
                            const std::string& mcu_device) {
  Instruments inst;
  RigCheckResult r = CheckRig(options, plan, mcu_device, &inst);
  if (inst.master) inst.master->SafeState();
  if (inst.slave) inst.slave->SafeState();
  return r;
}

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
  try {
    background_device = rig_operator.PrepareHallRecording(HallRun::kBackground);
  } catch (const std::exception& e) {
    result.rig_check.problems.push_back(std::string("Hall MCU: ") + e.what());
  }
  if (result.rig_check.problems.empty())
    result.rig_check = CheckRig(options, &plan, background_device, &inst);
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
  auto safe_state = [&] {
    const bool ok = rig.SafeState();
    log.Line(ok ? "safe state: generator outputs off (confirmed)"
                : "safe state: outputs off NOT confirmed by both generators");
    result.safe_state_confirmed = ok;
  };
  // Explicit paths below run safe_state() and Disarm() the guard, so the guard's own action runs
  // only on SIGINT/SIGTERM.
  gen::SafeStateGuard guard([&] {
    log.Line("interrupted (SIGINT/SIGTERM): switching generator outputs off");
    safe_state();
  });
  int accepted_total = 0;
  std::vector<dataset::Step1Frame> step1_kept;
  std::vector<dataset::Step2Frame> step2_kept;
  try {
    const gen::RigSignalPlan signals = PlanSessionSignals(options.generators.signals, plan);
    rig.Apply(signals);
    rig.VerifyLock();
    char buf[200];
    std::snprintf(
        buf, sizeof(buf),
        "generators: drives, clock and the plan's %zu laser triggers (arb %lld points "
        "at %.6g Sa/s, max quantisation %.3g us) applied, outputs on, locked",
        signals.trigger.times_s.size(), static_cast<long long>(signals.trigger.arb.points),
        signals.trigger.arb.sample_rate_sps, signals.trigger.max_quantisation_error_s * 1e6);
    log.Line(buf);

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
            throw std::runtime_error(
                file + ": camera: " + std::string(camera::FrameStatusName(fr.status)) + " " +
                fr.message);
          if (rig_operator.FrameShowsCurrentSetup(fr.frame.info())) image = FrameToMat(fr.frame);
        }
        GateResult g;
        g.accepted = true;
        if (options.run_quality_gate)
          g = CheckFrame(image, step, expected, plan.world_board, plan.sliding_board, options.gate);
        if (g.accepted) {
          interchange::WriteImageAtomically(out / file, image);
          fo.accepted = true;
          fo.reason.clear();
          return fo;
        }
        fo.reason = g.reason;
        if (attempt + 1 == options.max_gate_attempts) {
          // Kept for inspection, outside the interchange layout.
          std::string name = file;
          for (char& c : name) c = c == '/' ? '_' : c;
          interchange::WriteImageAtomically(out / "rejected" / name, image);
        }
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
      const auto r = RecordHall(*inst.mcu, out / "hall" / "background.csv", options,
                                options.background_seconds, nullptr);
      result.background_readings = r.counts.readings_delivered;
      result.background_edges = r.counts.edges_delivered;
      log.Line("Hall: background " + std::to_string(r.counts.readings_delivered) + " readings, " +
               std::to_string(r.counts.edges_delivered) + " clock edges, " +
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
    const auto r = RecordHall(*actual_mcu, out / "hall" / "actual.csv", options, 0.0, [&] {
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
           std::to_string(plan.step1.size()) + " step-1 and " + std::to_string(step2_kept.size()) +
           "/" + std::to_string(plan.step2.size()) + " step-2 frames accepted");
  return result;
}

}  // namespace msmcal::orchestrator
