#include "sessions/orchestrator/orchestrator.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <stdexcept>
#include <thread>

#include "acquisition/frames/frame_writer.h"
#include "acquisition/hall/hall_csv_writer.h"
#include "acquisition/hall/hall_recorder.h"
#include "drivers/generator/function_generator.h"
#include "drivers/generator/rig_generators.h"
#include "drivers/generator/safe_state.h"
#include "drivers/generator/watchdog.h"
#include "processing/signal/rig_signals.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/orchestrator/reference_steps.h"
#include "sessions/store/session_store.h"

namespace msmcal::orchestrator {

namespace fs = std::filesystem;

std::string OrchestratorOptions::Validate() const {
  if (out_dir.empty()) return "OrchestratorOptions.out_dir is empty: a session folder is needed";
  if (camera.empty()) return "OrchestratorOptions.camera is empty";
  if (!(camera_frame_rate_hz > 0))
    return "OrchestratorOptions.camera_frame_rate_hz = " + std::to_string(camera_frame_rate_hz) +
           ": must be > 0";
  if (frame_timeout_ms <= 0)
    return "OrchestratorOptions.frame_timeout_ms = " + std::to_string(frame_timeout_ms) +
           ": must be > 0";
  if (max_stale_frames < 0)
    return "OrchestratorOptions.max_stale_frames = " + std::to_string(max_stale_frames) +
           ": must be >= 0";
  if (!(drive_settle_periods >= 0 && drive_settle_periods <= 1000))
    return "OrchestratorOptions.drive_settle_periods = " + std::to_string(drive_settle_periods) +
           ": must be in [0, 1000]";
  if (max_gate_attempts < 1)
    return "OrchestratorOptions.max_gate_attempts = " + std::to_string(max_gate_attempts) +
           ": must be >= 1";
  if (!(background_seconds >= 0))
    return "OrchestratorOptions.background_seconds = " + std::to_string(background_seconds) +
           ": must be >= 0";
  if (!(actual_min_seconds >= 0 && actual_min_seconds <= 86400))
    return "OrchestratorOptions.actual_min_seconds = " + std::to_string(actual_min_seconds) +
           ": must be in [0, 86400]";
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
// from the safe-state watcher thread. Times are the injected clock's.
class SessionLog {
 public:
  SessionLog(const fs::path& file, ProgressFn progress, store::SessionStore* journal,
             const store::Clock& clock)
      : progress_(std::move(progress)), journal_(journal), clock_(clock), start_ns_(clock.NowNs()) {
    file_ = std::fopen(file.string().c_str(), "a");
    if (!file_) throw std::runtime_error(file.string() + ": cannot open the session log");
  }
  ~SessionLog() {
    if (file_) std::fclose(file_);
  }
  SessionLog(const SessionLog&) = delete;
  SessionLog& operator=(const SessionLog&) = delete;
  // Generator time: seconds since the generators' start trigger (*TRG to unit 1), on the
  // session's clock, so to within the LAN latency; none while the outputs are off.
  void SetGeneratorEpoch(std::optional<int64_t> epoch_ns) {
    std::lock_guard<std::mutex> lock(mu_);
    generator_epoch_ns_ = epoch_ns;
  }
  void Line(const std::string& text, const char* kind = "info") {
    const int64_t now_ns = clock_.NowNs();
    std::optional<double> generator_time_s;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (generator_epoch_ns_) generator_time_s = 1e-9 * double(now_ns - *generator_epoch_ns_);
    }
    if (journal_) {
      try {
        journal_->AddEvent(kind, text, generator_time_s);
      } catch (const std::exception& e) {
        // The text file below still has it; say so once there.
        std::lock_guard<std::mutex> lock(mu_);
        std::fprintf(file_, "journal: event not stored: %s\n", e.what());
      }
    }
    {
      std::lock_guard<std::mutex> lock(mu_);
      std::fprintf(file_, "[%8.3f s] %s\n", 1e-9 * double(now_ns - start_ns_), text.c_str());
      std::fflush(file_);
    }
    // Outside the lock: the safe-state watcher may log while the callback runs.
    if (progress_) progress_(text);
  }

 private:
  std::mutex mu_;
  std::FILE* file_ = nullptr;
  ProgressFn progress_;
  store::SessionStore* journal_;
  const store::Clock& clock_;
  const int64_t start_ns_;
  std::optional<int64_t> generator_epoch_ns_;
};

// generators_transcript.txt: one line per SCPI exchange ("unit1 > *RST", "unit1 < 1"), without
// times (so that a replay's transcript compares equal). Thread-safe (the safe-state watcher
// talks to the generators too).
class TranscriptFile {
 public:
  explicit TranscriptFile(const fs::path& file) {
    file_ = std::fopen(file.string().c_str(), "a");
    if (!file_) throw std::runtime_error(file.string() + ": cannot open the SCPI transcript");
  }
  ~TranscriptFile() { std::fclose(file_); }
  scpi::TranscriptSink Sink(const std::string& unit) {
    return [this, unit](const scpi::TranscriptEntry& e) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        std::fprintf(file_, "%s %c %s\n", unit.c_str(), e.to_instrument ? '>' : '<',
                     e.text.c_str());
        std::fflush(file_);
      }
      if (on_trigger_ && unit == "unit1" && e.to_instrument && e.text == "*TRG") on_trigger_();
    };
  }
  // Called when the start trigger goes to unit 1 (the generators' time zero).
  void OnStartTrigger(std::function<void()> f) { on_trigger_ = std::move(f); }
  void Comment(const std::string& text) {
    std::lock_guard<std::mutex> lock(mu_);
    std::fprintf(file_, "# %s\n", text.c_str());
    std::fflush(file_);
  }

 private:
  std::mutex mu_;
  std::FILE* file_ = nullptr;
  std::function<void()> on_trigger_;
};

// The frame as the solver would read it from its PNG (frames::FrameImage), owning its pixels.
cv::Mat FrameToMat(const camera::Frame& frame) {
  const cv::Mat image = frames::FrameImage(frame);
  return image.data == frame.data() ? image.clone() : image;
}

// Streams the camera to OrchestratorOptions::on_live_frame while the operator is asked (see
// LiveFrame): constructed just before a frame's generator change (Play) and its
// RigOperator::Prepare* call, or a Hall recording's Prepare call, destroyed (stopped and
// joined) when they return or throw. Does nothing without a streaming camera or an observer. A
// camera error ends the pump quietly: the orchestrator's next grab meets it and reports it.
// The camera is used by one thread at a time, as camera::Camera requires: the pump's thread
// between the constructor and the join in the destructor, the orchestrator's otherwise.
class LivePump {
 public:
  LivePump(camera::Camera* cam, const LiveFrameObserver& observer, int step, size_t index,
           std::string hall_recording = "") {
    if (!cam || !observer) return;
    thread_ = std::thread([this, cam, &observer, step, index, hall_recording] {
      while (!stop_.load()) {
        camera::FrameResult fr = cam->NextFrame(/*timeout_us=*/100'000);
        if (fr.status == camera::FrameStatus::kTimeout) continue;
        if (fr.status != camera::FrameStatus::kOk) return;
        const cv::Mat image = FrameToMat(fr.frame);
        LiveFrame live;
        live.step = step;
        live.index = index;
        live.image = &image;
        live.host_timestamp_ns = fr.frame.info().host_timestamp_ns;
        live.hall_recording = hall_recording;
        try {
          observer(live);
        } catch (...) {  // the live view never stops a session
        }
      }
    });
  }
  ~LivePump() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  LivePump(const LivePump&) = delete;
  LivePump& operator=(const LivePump&) = delete;

 private:
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

int ExpectedDots(const dataset::Step1Frame& f) { return static_cast<int>(f.beams.size()); }
int ExpectedDots(const dataset::Step2Frame& f) {
  return static_cast<int>(f.beams.size() * std::max<size_t>(1, f.triggers.size()));
}

// The factory the options name, or the drivers'.
InstrumentFactory& Instruments(const OrchestratorOptions& options) {
  static const std::shared_ptr<InstrumentFactory> drivers = MakeDriverInstruments();
  return options.instruments ? *options.instruments : *drivers;
}

struct OpenInstruments {
  std::unique_ptr<gen::FunctionGenerator> master, slave;
  std::unique_ptr<camera::Camera> cam;
  std::unique_ptr<hall_mcu::HallSensor> mcu;  // the background MCU link, checked
};

RigCheckResult CheckRig(const OrchestratorOptions& options, const dataset::Recording* plan,
                        const std::string& mcu_device, OpenInstruments* inst,
                        TranscriptFile* transcript = nullptr) {
  RigCheckResult r;
  InstrumentFactory& instruments = Instruments(options);
  // Generators: identity (on open), reference lock, signal design within limits.
  auto open_generator = [&](int unit, const gen::Keysight33500Options& o,
                            std::unique_ptr<gen::FunctionGenerator>* g) {
    const std::string name = "unit" + std::to_string(unit);
    try {
      *g = instruments.OpenGenerator(o, transcript ? transcript->Sink(name) : nullptr);
      const common::Result<scpi::Identity> id = (*g)->Identify();
      if (!id.ok()) throw std::runtime_error(id.status().message);
      r.found.push_back(o.name + ": " + id->model);
      r.instruments.emplace_back(
          o.name, id->manufacturer + " " + id->model + " " + id->serial + " " + id->firmware);
    } catch (const std::exception& e) {
      r.problems.push_back("generator " + std::to_string(unit) + " (" + o.link.host + ":" +
                           std::to_string(o.link.port) + "): " + e.what());
    }
  };
  open_generator(1, options.generators.unit1, &inst->master);
  open_generator(2, options.generators.unit2, &inst->slave);
  if (inst->master && inst->slave) {
    try {
      // The first failure ends the check (what follows depends on it).
      common::Status s = inst->master->Reset();
      if (s) s = inst->slave->Reset();
      if (s) s = inst->master->SetReference(gen::ReferenceSource::kInternal);
      if (s) s = inst->slave->SetReference(gen::ReferenceSource::kExternal);
      common::Result<bool> locked = s ? inst->slave->ReferenceLocked() : common::Result<bool>(s);
      if (!locked.ok())
        r.problems.push_back("generator reference check: " + locked.status().message);
      else if (!*locked)
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
  // A frame must collect every trigger of its pattern: expose at least one pattern period.
  if (options.camera_exposure_us) {
    try {
      const double period_s = signal::PatternPeriod(options.generators.signals.fast.frequency_hz,
                                                    options.generators.signals.slow.frequency_hz);
      if (*options.camera_exposure_us < period_s * 1e6 * (1 - 1e-9)) {
        char buf[240];
        std::snprintf(buf, sizeof(buf),
                      "camera.exposure_us = %.6g is shorter than the drives' pattern period "
                      "%.6g us: a frame would miss triggers of its pattern",
                      *options.camera_exposure_us, period_s * 1e6);
        r.problems.push_back(buf);
      }
    } catch (const std::exception&) {
      // The signal design's own problem is listed above.
    }
  }
  // Camera: sensor size and pixel format.
  camera::OpenCameraResult opened = instruments.OpenCamera(options.camera);
  if (!opened.camera) {
    r.problems.push_back("camera " + options.camera + ": " + opened.error);
  } else {
    inst->cam = std::move(opened.camera);
    const camera::CameraInfo info = inst->cam->Info();
    r.found.push_back("camera " + info.vendor + " " + info.model + " " + info.serial + " " +
                      std::to_string(info.sensor_width) + "x" + std::to_string(info.sensor_height));
    r.instruments.emplace_back("camera", info.vendor + " " + info.model + " " + info.serial + " " +
                                             std::to_string(info.sensor_width) + "x" +
                                             std::to_string(info.sensor_height));
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
      config.exposure_us = options.camera_exposure_us;
      config.buffer_count = 4;
      if (camera::Status s = inst->cam->Configure(config); !s)
        r.problems.push_back("camera configuration (Mono8, full sensor): " + s.message);
    }
  }
  // Hall MCU: identity and a status frame on the link.
  try {
    hall_mcu::HallMcuOptions link = options.mcu;
    link.device = mcu_device;
    inst->mcu = instruments.OpenHallSensor(link);
    hall_mcu::DeviceInfo dev;
    if (auto c = inst->mcu->Identify(&dev); !c.ok) {
      r.problems.push_back("Hall MCU " + link.device + ": " + c.message);
    } else if (auto s = inst->mcu->RequestStatus(); !s.ok) {
      r.problems.push_back("Hall MCU " + link.device + ": no status: " + s.message);
    } else {
      r.found.push_back("Hall MCU " + link.device + ": " + dev.ToString());
      r.instruments.emplace_back("hall_mcu", dev.ToString());
    }
  } catch (const std::exception& e) {
    r.problems.push_back(std::string("Hall MCU: ") + e.what());
  }
  r.ok = r.problems.empty();
  return r;
}

// Reports a running Hall recording's counts to OrchestratorOptions::on_rig_status about twice a
// second from a thread of its own, and once more (no recording running) when destroyed. Only
// used while the generator outputs are on and locked (RecordHall runs after the rig's Apply).
class HallStatusReporter {
 public:
  HallStatusReporter(const RigStatusObserver& observer, std::string name,
                     const acquisition::HallRecorder& recorder)
      : observer_(observer), recorder_(recorder) {
    if (!observer_) return;
    thread_ = std::thread([this, name = std::move(name)] {
      std::unique_lock<std::mutex> lock(mutex_);
      do {
        lock.unlock();
        Report(name);
        lock.lock();
      } while (!cv_.wait_for(lock, std::chrono::milliseconds(500), [this] { return stop_; }));
    });
  }
  ~HallStatusReporter() {
    if (!thread_.joinable()) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
    Report("");
  }
  HallStatusReporter(const HallStatusReporter&) = delete;
  HallStatusReporter& operator=(const HallStatusReporter&) = delete;

 private:
  void Report(const std::string& name) {
    const acquisition::HallRecorderCounts c = recorder_.Counts();
    RigStatus st;
    st.outputs_on = true;
    st.reference_locked = true;
    st.hall_recording = name;
    st.hall_readings = c.readings_delivered;
    st.hall_lost = c.driver.readings_lost + c.readings_dropped;
    st.hall_seconds = c.seconds_recorded;
    try {
      observer_(st);
    } catch (...) {  // an observer never stops a recording
    }
  }
  const RigStatusObserver& observer_;
  const acquisition::HallRecorder& recorder_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;
};

// Records one Hall recording into hall/<name>.csv through the driver; returns the recorder's
// result. Throws when the recording ended abnormally, the sink (CSV writer) failing included.
// With `during`, the recording runs while it does and is stopped when it returns; `during` calls
// its argument between its own steps, which throws as soon as the sink has failed; when it
// returns before the recording covers min_seconds of MCU time, the recording goes on until it
// does (or the MCU's data end, or the recording ends otherwise). Without `during`, it runs for
// max_seconds of MCU time (or to the end of the MCU's data).
acquisition::HallRecorderResult RecordHall(
    hall_mcu::HallSensor& sensor, const fs::path& csv, const OrchestratorOptions& options,
    double max_seconds, const std::function<void(const std::function<void()>&)>& during,
    double min_seconds = 0, SessionLog* log = nullptr) {
  // Shared with the sink: a hung sink thread is abandoned by the recorder with its captures.
  auto writer = std::make_shared<acquisition::HallCsvWriter>(csv);
  acquisition::HallRecorderOptions ro;
  ro.max_seconds = max_seconds;
  ro.rate_hz = options.mcu_rate_hz;
  acquisition::HallRecorder recorder(
      sensor,
      [writer, hook = options.hall_sink_hook](const hall_mcu::HallBatch& b) {
        if (hook) hook(b);
        writer->Write(b);
      },
      ro);
  recorder.Start();
  const std::string who = csv.filename().string() + ": Hall recording";
  std::exception_ptr error;
  acquisition::HallRecorderResult result;
  {
    HallStatusReporter status(options.on_rig_status, csv.stem().string(), recorder);
    try {
      if (during) {
        const auto check_sink = [&] {
          if (std::string e = recorder.SinkError(); !e.empty())
            throw std::runtime_error(who + " failed: " + e);
        };
        during(check_sink);
        if (min_seconds > 0 && recorder.Counts().seconds_recorded < min_seconds) {
          if (log) {
            char line[200];
            std::snprintf(line, sizeof(line),
                          "Hall: %s recording held until it covers %g s of MCU time (%.1f s so "
                          "far)",
                          csv.stem().c_str(), min_seconds, recorder.Counts().seconds_recorded);
            log->Line(line);
          }
          // The reader ends by itself at the end of the MCU's data, a stall or a closed device.
          while (!recorder.WaitForReader(std::chrono::milliseconds(50))) {
            check_sink();
            if (recorder.Counts().seconds_recorded >= min_seconds) break;
          }
        }
        recorder.Stop();
      }
    } catch (...) {
      error = std::current_exception();
      recorder.Stop();
    }
    result = recorder.Wait();
  }
  const bool sink_ok = result.end != acquisition::RecorderEnd::kSinkFailed &&
                       result.end != acquisition::RecorderEnd::kSinkHung;
  if (sink_ok) writer->Close();
  if (error) std::rethrow_exception(error);
  if (result.end != acquisition::RecorderEnd::kEndOfData &&
      result.end != acquisition::RecorderEnd::kDuration &&
      result.end != acquisition::RecorderEnd::kStopped) {
    throw std::runtime_error(who + " ended: " + acquisition::ToString(result.end) + " " +
                             result.message);
  }
  return result;
}

}  // namespace

namespace {

// The session plan with the laser arb rebuilt from `triggers` (plan trigger entries): each at the
// arb sample nearest its t_s, so the laser fires within half a sample of the time session.yaml
// records. `what` names the table in messages.
gen::RigSignalPlan PlanWithTriggers(const gen::RigSignalsConfig& config,
                                    const dataset::Recording& plan,
                                    const std::vector<dataset::Trigger>& triggers) {
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
  for (const auto& t : triggers) {
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
  d.duty = static_cast<double>(d.pulse_samples * static_cast<int64_t>(triggers.size())) /
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

}  // namespace

gen::RigSignalPlan PlanSessionSignals(const gen::RigSignalsConfig& config,
                                      const dataset::Recording& plan) {
  return PlanWithTriggers(config, plan, plan.triggers);
}

FrameSignals Step1Signals(const dataset::Recording& plan) {
  FrameSignals s;
  if (!plan.triggers.empty()) s.triggers = {plan.triggers.front().j};
  return s;
}

FrameSignals Step2Signals(const dataset::Recording& plan, const dataset::Step2Frame& frame) {
  FrameSignals s;
  switch (frame.kind) {
    case dataset::Step2Kind::kNeutral:
      return Step1Signals(plan);
    case dataset::Step2Kind::kFastOnly:
      s.fast_on = true;
      break;
    case dataset::Step2Kind::kScan:
      s.fast_on = s.slow_on = true;
      break;
  }
  s.triggers = frame.triggers;
  return s;
}

FrameSignals BackgroundSignals(const dataset::Recording& plan) {
  FrameSignals s = Step1Signals(plan);
  s.fast_on = s.slow_on = true;
  return s;
}

gen::RigSignalPlan PlanFrameSignals(const gen::RigSignalsConfig& config,
                                    const dataset::Recording& plan, const FrameSignals& frame) {
  std::vector<dataset::Trigger> triggers;
  for (int j : frame.triggers) {
    const auto it = std::find_if(plan.triggers.begin(), plan.triggers.end(),
                                 [j](const dataset::Trigger& t) { return t.j == j; });
    if (it == plan.triggers.end())
      throw std::invalid_argument("session plan: a frame names trigger " + std::to_string(j) +
                                  ", which is not in the trigger table");
    triggers.push_back(*it);
  }
  if (triggers.empty())
    throw std::invalid_argument("session plan: a frame's laser pattern has no trigger");
  return PlanWithTriggers(config, plan, triggers);
}

RigCheckResult CheckRigOnly(const OrchestratorOptions& options, const dataset::Recording* plan,
                            const std::string& mcu_device) {
  OpenInstruments inst;
  RigCheckResult r = CheckRig(options, plan, mcu_device, &inst);
  if (inst.master) inst.master->SafeState();
  if (inst.slave) inst.slave->SafeState();
  return r;
}

RigCheckError::RigCheckError(const RigCheckResult& result)
    : std::runtime_error(JoinLines(result.problems)), result_(result) {}

namespace {

constexpr const char* kPlanSessionYamlKey = "plan.session_yaml";
constexpr const char* kPlanCameraYamlKey = "plan.camera_yaml";
constexpr const char* kRunKindKey = "run.kind";

// Where a frame the gate finally rejected is kept: rejected/<step>_<name>.png.
std::string RejectedFile(const std::string& file) {
  std::string name = file;
  for (char& c : name) c = c == '/' ? '_' : c;
  return "rejected/" + name;
}

std::string QualityJson(const GateResult& g, bool gate_ran, int attempt,
                        const std::string& plan_file) {
  nlohmann::json j;
  j["plan_file"] = plan_file;
  j["gate"] = gate_ran;
  j["attempt"] = attempt;
  if (gate_ran) {
    j["dots_found"] = g.dots_found;
    j["dots_expected"] = g.dots_expected;
    j["saturated_fraction"] = g.saturated_fraction;
    int boards = 0;
    for (const auto& b : g.boards) boards += b ? 1 : 0;
    j["boards_found"] = boards;
    if (!g.reason.empty()) j["reason"] = g.reason;
  }
  return j.dump();
}

// Moves a Hall recording cut short (and its clock and reset files) aside as
// <name>.partial-<n>.csv; returns the new readings file names.
std::vector<std::string> KeepPartialHall(const fs::path& hall_dir, const std::string& name) {
  std::vector<std::string> kept;
  if (!fs::exists(hall_dir / (name + ".csv"))) return kept;
  int n = 1;
  while (fs::exists(hall_dir / (name + ".partial-" + std::to_string(n) + ".csv"))) ++n;
  const std::string tag = ".partial-" + std::to_string(n);
  std::vector<fs::path> files;  // collected first: no renames while iterating
  for (const auto& entry : fs::directory_iterator(hall_dir)) files.push_back(entry.path());
  for (const auto& path : files) {
    const std::string f = path.filename().string();
    // name.csv, name_clock.csv, name-reset<N>.csv, name-reset<N>_clock.csv
    if (f.rfind(name, 0) != 0 || path.extension() != ".csv") continue;
    const std::string rest = f.substr(name.size());
    if (!(rest == ".csv" || rest == "_clock.csv" || rest.rfind("-reset", 0) == 0)) continue;
    const std::string stem = f.substr(0, f.size() - 4);
    const std::string moved = name + tag + stem.substr(name.size()) + ".csv";
    fs::rename(path, hall_dir / moved);
    if (rest == ".csv") kept.push_back("hall/" + moved);
  }
  return kept;
}

bool StepDone(const store::SessionStore& journal, const char* name) {
  for (const auto& [n, state] : journal.Steps())
    if (n == name) return state == store::StepState::kDone;
  return false;
}

// The event (and log line) of a Hall recording starting.
SessionEvent HallStarted(const std::string& name, const std::string& device, SessionLog& log) {
  SessionEvent e;
  e.kind = SessionEvent::Kind::kHallStarted;
  e.recording = name;
  e.device = device;
  e.text = "Hall: " + name + " recording on " + device + (name == "actual" ? " during step 2" : "");
  log.Line(e.text);
  return e;
}

}  // namespace

SessionJournalState ReadSessionJournal(const fs::path& dir) {
  SessionJournalState st;
  if (!fs::exists(dir / store::kSessionDbName)) return st;
  const store::SystemClock clock;
  auto journal = store::SessionStore::Open(dir, clock, /*read_only=*/true);
  st.exists = true;
  st.run_kind = journal->GetMeta(kRunKindKey).value_or("");
  st.run_config_yaml = journal->ConfigYaml();
  st.rig_id = journal->GetMeta("rig_id").value_or("");
  st.mirror_id = journal->GetMeta("mirror_id").value_or("");
  st.note = journal->GetMeta("note").value_or("");
  for (const auto& [name, state] : journal->Steps()) {
    st.steps.emplace_back(name, store::ToString(state));
    if (name == kStepSessionWritten && state == store::StepState::kDone) st.complete = true;
  }
  st.frames_recorded = journal->Frames().size();
  return st;
}

dataset::Recording LoadSessionPlan(const fs::path& dir) {
  if (!fs::exists(dir / store::kSessionDbName))
    throw std::runtime_error(dir.string() + ": no session journal (" + store::kSessionDbName +
                             ") here");
  const store::SystemClock clock;
  auto journal = store::SessionStore::Open(dir, clock, /*read_only=*/true);
  const auto session_yaml = journal->GetMeta(kPlanSessionYamlKey);
  const auto camera_yaml = journal->GetMeta(kPlanCameraYamlKey);
  if (!session_yaml || !camera_yaml)
    throw std::runtime_error(dir.string() + ": the journal holds no session plan (meta " +
                             kPlanSessionYamlKey + "): not written by a session run");
  dataset::Recording plan;
  const std::string where = (dir / store::kSessionDbName).string();
  interchange::ParseSessionYaml(*session_yaml, where + " [" + kPlanSessionYamlKey + "]", &plan);
  plan.camera = interchange::ParseCameraYaml(*camera_yaml, where + " [" + kPlanCameraYamlKey + "]");
  return plan;
}

std::unique_ptr<store::SessionStore> CreateSessionJournal(const OrchestratorOptions& options,
                                                          const dataset::Recording& plan,
                                                          const fs::path& dir,
                                                          const store::Clock& clock) {
  if (fs::exists(dir) && !fs::is_empty(dir))
    throw std::runtime_error(dir.string() + ": session folder exists and is not empty");
  store::SessionMetadata meta;
  meta.rig_id = options.rig_id;
  meta.mirror_id = options.mirror_id;
  meta.note = options.note;
  meta.description = plan;
  meta.config_yaml = options.run_config_yaml;
  auto journal = store::SessionStore::Create(dir, meta, clock);
  journal->SetMeta(kRunKindKey, options.run_kind);
  journal->SetMeta(kPlanSessionYamlKey, interchange::FormatSessionYaml(plan));
  journal->SetMeta(kPlanCameraYamlKey, interchange::FormatCameraYaml(plan.camera));
  journal->SetTriggers(plan.triggers);
  for (const char* step : {kStepRigCheck, kStep1, kStepBackground, kStep2, kStepSessionWritten})
    journal->SetStep(step, store::StepState::kPending);
  return journal;
}

namespace {

// The session as a controller (issue 16): RunSession's steps as named methods that read top to
// bottom in Run(): open the journal, check the rig, arm the safe state, start the signals,
// step 1, the background Hall recording, step 2 with the actual Hall recording, write the
// session. The threads live apart from the run logic: the camera's live pump (LivePump), the
// Hall recorder and its status reporter (RecordHall), the safe-state watcher (SafeStateGuard),
// the watchdog (a process). Every fact is a typed SessionEvent to options.on_event, its text a
// line of session_log.txt; time is the injected clock's (options.clock).
class SessionController {
 public:
  SessionController(const OrchestratorOptions& options, const dataset::Recording& plan,
                    RigOperator& rig_operator, const ProgressFn& progress)
      : options_(options),
        plan_(plan),
        operator_(rig_operator),
        progress_(progress),
        out_(options.out_dir),
        clock_(options.clock ? *options.clock : system_clock_) {}

  SessionResult Run() {
    OpenJournal();
    if (AlreadyComplete()) return result_;
    CheckTheRig();
    ArmTheSafeState();
    try {
      StartTheSignals();
      Step1();
      BackgroundHallRecording();
      Step2WithTheActualHallRecording();
      inst_.cam->Stop();
    } catch (const std::exception& e) {
      log_->Line(std::string("ERROR: ") + e.what(), "error");
      // Outputs off first: stopping a camera that is gone can take seconds (its control times
      // out).
      SafeState();
      guard_->Disarm();  // outputs are off already
      if (inst_.cam) inst_.cam->Stop();
      if (handed_over_)
        throw gen::SafeStateNotConfirmed(handed_over_->exit_status,
                                         std::string(e.what()) + "; then " + handed_over_->text);
      throw;
    }
    SafeState();
    guard_->Disarm();
    if (handed_over_)
      throw gen::SafeStateNotConfirmed(handed_over_->exit_status, handed_over_->text);
    WriteTheSession();
    return result_;
  }

 private:
  // --- The steps -------------------------------------------------------------------------------

  // Creates the session's journal, or opens it to resume (the plan must be the one it was started
  // with); the folders, the session log and the SCPI transcript.
  void OpenJournal() {
    const std::string plan_yaml = interchange::FormatSessionYaml(plan_);
    if (options_.resume) {
      if (!fs::exists(out_ / store::kSessionDbName))
        throw std::runtime_error(out_.string() + ": no session journal (" + store::kSessionDbName +
                                 ") to resume");
      journal_ = store::SessionStore::Open(out_, clock_);
      if (journal_->GetMeta(kPlanSessionYamlKey).value_or("") != plan_yaml ||
          journal_->GetMeta(kPlanCameraYamlKey).value_or("") !=
              interchange::FormatCameraYaml(plan_.camera))
        throw std::runtime_error(out_.string() +
                                 ": the plan given differs from the plan this session was "
                                 "started with (LoadSessionPlan gives the stored one)");
      for (const auto& f : journal_->Frames()) {
        // Rejected frames are kept under rejected/; quality_json names the plan's file.
        const auto q = nlohmann::json::parse(f.quality_json, nullptr, false);
        std::string plan_file = f.file;
        if (q.is_object() && q.contains("plan_file")) plan_file = q["plan_file"].get<std::string>();
        recorded_[plan_file] = f.accepted;
      }
    } else {
      journal_ = CreateSessionJournal(options_, plan_, out_, clock_);
    }
    fs::create_directories(out_ / "step1");
    fs::create_directories(out_ / "step2");
    fs::create_directories(out_ / "hall");
    log_ =
        std::make_unique<SessionLog>(out_ / "session_log.txt", progress_, journal_.get(), clock_);
    transcript_ = std::make_unique<TranscriptFile>(out_ / "generators_transcript.txt");
    transcript_->OnStartTrigger([this] { log_->SetGeneratorEpoch(clock_.NowNs()); });
    result_.folder = out_;
    result_.resumed = options_.resume;
  }

  // On a resume of a session whose session.yaml is written: nothing to acquire.
  bool AlreadyComplete() {
    if (!options_.resume) {
      log_->Line("session " + out_.string() + ": " + std::to_string(plan_.step1.size()) +
                 " step-1 frames, " + std::to_string(plan_.step2.size()) + " step-2 frames, " +
                 std::to_string(plan_.triggers.size()) + " triggers");
      return false;
    }
    transcript_->Comment("resumed");
    log_->Line("session " + out_.string() + " RESUMED: " + std::to_string(recorded_.size()) +
               " frames already recorded are kept");
    if (!StepDone(*journal_, kStepSessionWritten)) return false;
    for (const auto& f : plan_.step1)
      result_.frames.push_back({f.file, Accepted(f.file), "", true});
    for (const auto& f : plan_.step2)
      result_.frames.push_back({f.file, Accepted(f.file), "", true});
    result_.safe_state_confirmed = true;
    log_->Line("session already complete (session.yaml written): nothing to acquire");
    return true;
  }

  // The rig check. The MCU is checked on options.mcu.device when given (then the operator sets
  // up the background recording when it is due); otherwise the operator's background device is
  // asked for now. A failed check ends with the outputs off and a RigCheckError.
  void CheckTheRig() {
    SetStep(kStepRigCheck, store::StepState::kRunning);
    // A signal in the rig check: every generator opened so far (or being opened) off through
    // the driver's registry, then the line in the session log (the command's
    // OpenGeneratorsGuard, if any, says it on stderr). Silent once the session's guard takes
    // over.
    std::atomic<bool> in_rig_check{true};
    gen::SafeStateGuard rig_check_guard([&] {
      if (!in_rig_check || gen::SafeStateGuard::HandlingSignal() == 0) return;
      const std::vector<gen::OpenGeneratorOutcome> off = gen::SafeStateOfOpenGenerators();
      bool all = true;
      for (const auto& o : off) all = all && o.confirmed;
      if (!all) gen::SafeStateGuard::ReportUnconfirmed();
      log_->Line("interrupted (signal) in the rig check: generator outputs " +
                     (off.empty() ? std::string("untouched (no generator connection open yet)")
                                  : gen::FormatOpenGeneratorOutcomes(off)),
                 "error");
    });
    background_device_ = options_.mcu.device;
    ask_background_later_ = !background_device_.empty();
    if (!ask_background_later_) {
      try {
        background_device_ = operator_.PrepareHallRecording(HallRun::kBackground);
      } catch (const std::exception& e) {
        result_.rig_check.problems.push_back(std::string("Hall MCU: ") + e.what());
      }
    }
    if (result_.rig_check.problems.empty())
      result_.rig_check = CheckRig(options_, &plan_, background_device_, &inst_, transcript_.get());
    for (const auto& f : result_.rig_check.found) log_->Line("rig check: " + f);
    for (const auto& [role, identity] : result_.rig_check.instruments)
      journal_->SetInstrument(role, identity);
    if (!result_.rig_check.ok) {
      for (const auto& p : result_.rig_check.problems)
        log_->Line("rig check PROBLEM: " + p, "error");
      if (inst_.master) inst_.master->SafeState();
      if (inst_.slave) inst_.slave->SafeState();
      log_->Line("refused to start; generator outputs off", "error");
      throw RigCheckError(result_.rig_check);
    }
    SetStep(kStepRigCheck, store::StepState::kDone);
    log_->Line("rig check passed");
    in_rig_check = false;
  }

  // From here on outputs may be on: safe state on signal, exception and exit; the watchdog for
  // SIGKILL and crashes, stood down once the outputs are confirmed off. Explicit paths run
  // SafeState() and Disarm() the guard, so the guard's own action runs only on a signal (INT,
  // TERM, HUP, QUIT): outputs off first, then the log line (the log may be a closed pipe).
  void ArmTheSafeState() {
    rig_ = std::make_unique<gen::RigGenerators>(*inst_.master, *inst_.slave);
    if (options_.watchdog.enabled()) {
      watchdog_ = gen::Watchdog::Start(
          options_.watchdog,
          gen::WatchdogConfigFor(options_.generators, (out_ / "session_log.txt").string()));
      log_->Line("watchdog armed (pid " + std::to_string(watchdog_->pid()) + ")");
    }
    guard_ = std::make_unique<gen::SafeStateGuard>([this] {
      SafeState();
      if (handed_over_)
        gen::SafeStateGuard::ReportHandedOver(handed_over_->confirmed, handed_over_->text);
      else if (!result_.safe_state_confirmed)
        gen::SafeStateGuard::ReportUnconfirmed();
      log_->Line(handed_over_
                     ? "interrupted (signal): generator outputs left to the watchdog (above)"
                     : "interrupted (signal): generator outputs switched off",
                 "error");
    });
  }

  // The whole trigger table is checked once (duty, times); the generators then start with step
  // 1's signals, locked. Each frame plays its own pattern afterwards (Play).
  void StartTheSignals() {
    (void)PlanSessionSignals(options_.generators.signals, plan_);
    playing_ = Step1Signals(plan_);
    const gen::RigSignalPlan signals =
        PlanFrameSignals(options_.generators.signals, plan_, playing_);
    rig_->Apply(signals, playing_.fast_on, playing_.slow_on);
    rig_->VerifyLock();
    char buf[240];
    std::snprintf(buf, sizeof(buf),
                  "generators: drives (outputs off), clock and a one-pulse laser pattern (arb "
                  "%lld points at %.6g Sa/s, max quantisation %.3g us) applied and started, "
                  "locked",
                  static_cast<long long>(signals.trigger.arb.points),
                  signals.trigger.arb.sample_rate_sps,
                  signals.trigger.max_quantisation_error_s * 1e6);
    log_->Line(buf);
    ReportRig(/*outputs_on=*/true);
    pattern_period_s_ = signals.trigger.pattern_period_s;
    if (camera::Status s = inst_.cam->Start(); !s)
      throw std::runtime_error("camera: start streaming: " + s.message);
  }

  // Step 1: sliding plate poses, MSM not mounted.
  void Step1() {
    if (StepDone(*journal_, kStep1)) {
      log_->Line("step 1: done before the resume");
      for (const auto& f : plan_.step1) {
        FrameOutcome fo;
        if (FromJournal(f.file, &fo)) result_.frames.push_back(fo);
      }
      return;
    }
    SetStep(kStep1, store::StepState::kRunning);
    for (size_t i = 0; i < plan_.step1.size(); ++i) {
      const auto& f = plan_.step1[i];
      FrameOutcome fo;
      if (!FromJournal(f.file, &fo)) {
        {
          // The generators' change (and its settle) runs inside the pump too (see Step2Frame).
          LivePump pump(inst_.cam.get(), options_.on_live_frame, 1, i);
          Play(Step1Signals(plan_), f.file);
          operator_.PrepareStep1Frame(i);
        }
        store::FrameRecord record;
        record.step = "step1";
        record.pose = f.pose;
        record.beams = f.beams;
        fo = Acquire(1, i, plan_.step1.size(), f.file, ExpectedDots(f), record);
      }
      Note(fo, i, plan_.step1.size(), "step 1");
    }
    SetStep(kStep1, store::StepState::kDone);
  }

  // The background Hall recording (mirror top frame removed, coils driven).
  void BackgroundHallRecording() {
    if (StepDone(*journal_, kStepBackground)) {
      log_->Line("Hall: background recording done before the resume");
      inst_.mcu.reset();
      return;
    }
    SetStep(kStepBackground, store::StepState::kRunning);
    KeepPartial("background");
    if (ask_background_later_) {
      std::string device;
      {
        LivePump pump(inst_.cam.get(), options_.on_live_frame, 0, 0);
        device = operator_.PrepareHallRecording(HallRun::kBackground);
      }
      if (device != background_device_) {
        inst_.mcu.reset();
        hall_mcu::HallMcuOptions link = options_.mcu;
        link.device = device;
        inst_.mcu = Instruments(options_).OpenHallSensor(link);
        background_device_ = device;
      }
    }
    Play(BackgroundSignals(plan_), "Hall background");
    Emit(HallStarted("background", background_device_, *log_));
    const auto r = [&] {
      // Nothing else takes frames during the background recording: the live view keeps its
      // camera image (issue 19; the view downscales and paces it, LiveViewOptions).
      LivePump pump(inst_.cam.get(), options_.on_live_frame, 0, 0, "background");
      return RecordHall(*inst_.mcu, out_ / "hall" / "background.csv", options_,
                        options_.background_seconds, nullptr);
    }();
    result_.background_readings = r.counts.readings_delivered;
    result_.background_edges = r.counts.edges_delivered;
    HallDone("background", r);
    SetStep(kStepBackground, store::StepState::kDone);
    inst_.mcu.reset();
  }

  // Step 2 (MSM mounted, camera at C2) with the actual Hall recording running through it.
  void Step2WithTheActualHallRecording() {
    if (StepDone(*journal_, kStep2)) return;
    SetStep(kStep2, store::StepState::kRunning);
    KeepPartial("actual");
    std::string actual_device;
    {
      LivePump pump(inst_.cam.get(), options_.on_live_frame, 0, 0);
      actual_device = operator_.PrepareHallRecording(HallRun::kActual);
    }
    hall_mcu::HallMcuOptions link = options_.mcu;
    link.device = actual_device;
    auto actual_mcu = Instruments(options_).OpenHallSensor(link);
    Emit(HallStarted("actual", actual_device, *log_));
    const auto r = RecordHall(*actual_mcu, out_ / "hall" / "actual.csv", options_, 0.0,
                              [&](const std::function<void()>& check_hall) {
                                for (size_t i = 0; i < plan_.step2.size(); ++i) {
                                  check_hall();
                                  Step2Frame(i);
                                }
                              },
                              options_.actual_min_seconds, log_.get());
    result_.actual_readings = r.counts.readings_delivered;
    result_.actual_edges = r.counts.edges_delivered;
    HallDone("actual", r);
    SetStep(kStep2, store::StepState::kDone);
  }

  void Step2Frame(size_t i) {
    const auto& f = plan_.step2[i];
    FrameOutcome fo;
    if (!FromJournal(f.file, &fo)) {
      {
        // Play (a new laser arb, drives switched and their settle of drive_settle_periods
        // pattern periods) uses only the generators: the live view keeps the camera meanwhile,
        // so during the actual Hall recording the page never stands still for a settle.
        LivePump pump(inst_.cam.get(), options_.on_live_frame, 2, i);
        Play(Step2Signals(plan_, f), f.file);
        operator_.PrepareStep2Frame(i);
      }
      store::FrameRecord record;
      record.step = "step2";
      record.kind = f.kind;
      record.beams = f.beams;
      record.triggers = f.triggers;
      fo = Acquire(2, i, plan_.step2.size(), f.file, ExpectedDots(f), record);
    }
    Note(fo, i, plan_.step2.size(), "step 2");
  }

  // session.yaml last: a folder with a session.yaml is complete. The frames kept are those
  // recorded as accepted (before a resume or now), in plan order.
  void WriteTheSession() {
    dataset::Recording rec = plan_;
    rec.hall_actual.reset();
    rec.hall_background.reset();
    rec.step1.clear();
    rec.step2.clear();
    for (const auto& f : plan_.step1)
      if (Accepted(f.file)) rec.step1.push_back(f);
    for (const auto& f : plan_.step2)
      if (Accepted(f.file)) rec.step2.push_back(f);
    if (std::string e = interchange::CheckRecording(rec); !e.empty())
      throw std::runtime_error("session after quality gates: " + e);
    interchange::WriteRecording(out_, rec);
    (void)interchange::ReadRecording(out_);  // reads back, Hall files included
    SetStep(kStepSessionWritten, store::StepState::kDone);
    SessionEvent written;
    written.kind = SessionEvent::Kind::kSessionWritten;
    written.step1_accepted = rec.step1.size();
    written.step2_accepted = rec.step2.size();
    written.text = "session written: " + std::to_string(rec.step1.size()) + "/" +
                   std::to_string(plan_.step1.size()) + " step-1 and " +
                   std::to_string(rec.step2.size()) + "/" + std::to_string(plan_.step2.size()) +
                   " step-2 frames accepted";
    log_->Line(written.text);
    Emit(written);
  }

  // --- What the steps share ------------------------------------------------------------------

  // One typed event per fact (its log line as `text`).
  void Emit(const SessionEvent& e) {
    if (options_.on_event) options_.on_event(e);
  }

  // Steps change state in the journal and as an event.
  void SetStep(const char* name, store::StepState state) {
    journal_->SetStep(name, state);
    SessionEvent e;
    e.kind = SessionEvent::Kind::kStepState;
    e.step_name = name;
    e.state = store::ToString(state);
    e.text = std::string("step ") + name + ": " + e.state;
    Emit(e);
  }

  void ReportRig(bool outputs_on) {
    if (!options_.on_rig_status) return;
    RigStatus st;
    st.outputs_on = outputs_on;
    st.reference_locked = outputs_on;
    try {
      options_.on_rig_status(st);
    } catch (...) {  // an observer never changes the safe state's path
    }
  }

  // Called by the main thread and by the signal watcher. Not confirmed by msmcal itself: the
  // watchdog is asked to act now (docs/watchdog.md), and the session ends with
  // SafeStateNotConfirmed (signal: the guard's exit status).
  void SafeState() {
    std::lock_guard<std::mutex> lock(safe_state_mu_);
    const bool ok = rig_->SafeState();
    if (ok && watchdog_) watchdog_->StandDown();
    if (!ok && watchdog_ && !handed_over_) handed_over_ = gen::HandOverToWatchdog(*watchdog_);
    log_->SetGeneratorEpoch(std::nullopt);
    SessionEvent e;
    e.kind = SessionEvent::Kind::kSafeState;
    e.confirmed = ok;
    e.text = ok ? "safe state: generator outputs off (confirmed)"
                : "safe state: outputs off NOT confirmed by both generators";
    log_->Line(e.text, ok ? "info" : "error");
    if (handed_over_) log_->Line(handed_over_->text, "error");
    result_.safe_state_confirmed = ok;
    Emit(e);
    ReportRig(/*outputs_on=*/!ok);
  }

  // Makes the generators play `want` (what a frame or a recording needs): a new laser pattern
  // through ReplaceLaserArb, drive outputs through SetDrives; never a re-arm, so the drives, the
  // laser and the clock keep the start trigger's time base. After a drive change, waits
  // drive_settle_periods pattern periods before returning.
  void Play(const FrameSignals& want, const std::string& what) {
    if (want == playing_) return;
    auto on_off = [](bool on) { return on ? "on" : "off"; };
    const bool drives = want.fast_on != playing_.fast_on || want.slow_on != playing_.slow_on;
    if (want.triggers != playing_.triggers) {
      const gen::RigSignalPlan p = PlanFrameSignals(options_.generators.signals, plan_, want);
      std::string ids;
      for (int j : want.triggers) ids += (ids.empty() ? "" : ",") + std::to_string(j);
      transcript_->Comment(what + ": laser pattern of triggers [" + ids +
                           "] (same arb, points and rate; not re-armed)");
      rig_->ReplaceLaserArb(p.unit2_ch1);
      log_->Line("generators: " + what + ": laser pattern " + std::to_string(want.triggers.size()) +
                 " trigger(s) [" + ids + "]");
    }
    if (drives) {
      transcript_->Comment(what + ": fast drive " + on_off(want.fast_on) + ", slow drive " +
                           on_off(want.slow_on));
      rig_->SetDrives(want.fast_on, want.slow_on);
    }
    playing_ = want;
    if (drives) {
      const double settle_s = options_.drive_settle_periods * pattern_period_s_;
      char line[200];
      std::snprintf(line, sizeof(line),
                    "generators: %s: fast drive %s, slow drive %s; settling %.3g s (%.3g "
                    "pattern periods)",
                    what.c_str(), on_off(want.fast_on), on_off(want.slow_on), settle_s,
                    options_.drive_settle_periods);
      log_->Line(line);
      // The drive's settle: generator time runs on the host's steady clock to within the LAN
      // latency; frames are asked for (and the operator's freshness starts) only afterwards.
      if (settle_s > 0) std::this_thread::sleep_for(std::chrono::duration<double>(settle_s));
    }
  }

  // Grabs a frame exposed after the current setup, runs the gate, journals the frame (image on
  // disk first).
  FrameOutcome Acquire(int step, size_t index, size_t count, const std::string& file, int expected,
                       store::FrameRecord record) {
    FrameOutcome fo;
    fo.file = file;
    for (int attempt = 0; attempt < options_.max_gate_attempts; ++attempt) {
      cv::Mat image;
      for (int stale = 0; image.empty(); ++stale) {
        if (stale > options_.max_stale_frames)
          throw std::runtime_error(file + ": no frame of the current setup after " +
                                   std::to_string(stale) + " frames");
        camera::FrameResult fr =
            inst_.cam->NextFrame(static_cast<int64_t>(options_.frame_timeout_ms) * 1000);
        if (fr.status != camera::FrameStatus::kOk)
          throw std::runtime_error(file +
                                   ": camera: " + std::string(camera::FrameStatusName(fr.status)) +
                                   " " + fr.message);
        if (operator_.FrameShowsCurrentSetup(fr.frame.info())) image = FrameToMat(fr.frame);
      }
      GateResult g;
      g.accepted = true;
      if (options_.run_quality_gate)
        g = CheckFrame(image, step, expected, plan_.world_board, plan_.sliding_board,
                       options_.gate);
      const bool last = g.accepted || attempt + 1 == options_.max_gate_attempts;
      if (options_.on_frame) {
        FrameReport report;
        report.step = step;
        report.index = index;
        report.count = count;
        report.file = file;
        report.attempt = attempt;
        report.accepted = g.accepted;
        report.final = last;
        report.gate = options_.run_quality_gate ? &g : nullptr;
        report.image = &image;
        options_.on_frame(report);
      }
      record.accepted = g.accepted;
      record.quality_json = QualityJson(g, options_.run_quality_gate, attempt, file);
      if (g.accepted) {
        record.file = file;
        journal_->AddFrame(record, image);
        recorded_[file] = true;
        fo.accepted = true;
        fo.reason.clear();
        return fo;
      }
      fo.reason = g.reason;
      if (last) {
        // Kept for inspection, outside the interchange layout.
        record.file = RejectedFile(file);
        journal_->AddFrame(record, image);
        recorded_[file] = false;
      }
    }
    return fo;
  }

  // A frame decided: its event and log line.
  void Note(const FrameOutcome& fo, size_t i, size_t n, const char* step) {
    SessionEvent e;
    e.kind = SessionEvent::Kind::kFrameDecided;
    e.step = step[5] == '1' ? 1 : 2;  // "step 1" | "step 2"
    e.index = i;
    e.count = n;
    e.file = fo.file;
    e.accepted = fo.accepted;
    e.from_journal = fo.from_journal;
    e.reason = fo.reason;
    e.text = std::string(step) + ": frame " + std::to_string(i + 1) + "/" + std::to_string(n) +
             " " + fo.file +
             (fo.from_journal ? (fo.accepted ? " accepted before the resume (kept)"
                                             : " rejected before the resume (kept)")
              : fo.accepted   ? " accepted"
                              : " REJECTED: " + fo.reason);
    log_->Line(e.text, fo.accepted ? "info" : "warning");
    result_.frames.push_back(fo);
    Emit(e);
  }

  // A frame recorded before a resume (accepted or rejected) is not taken again.
  bool FromJournal(const std::string& file, FrameOutcome* fo) const {
    const auto it = recorded_.find(file);
    if (it == recorded_.end()) return false;
    fo->file = file;
    fo->accepted = it->second;
    fo->from_journal = true;
    return true;
  }

  bool Accepted(const std::string& file) const {
    const auto it = recorded_.find(file);
    return it != recorded_.end() && it->second;
  }

  // A Hall recording into hall/<name>.csv, journalled once complete. The journal reads the CSV
  // back rather than keeping its own copy of the batches: one conversion from MCU frames to
  // readings (the writer's, with its reset handling), and the journal holds exactly what the
  // interchange folder holds.
  void HallDone(const std::string& name, const acquisition::HallRecorderResult& r) {
    const fs::path csv = out_ / "hall" / (name + ".csv");
    // An MCU reset restarts MCU time: the writer put the readings after it into
    // <name>-reset<N>.csv. The recording is not continuous, so it is not journalled as done (the
    // session used to go on silently with the part before the reset): the session stops, and
    // `msmcal resume` keeps the pieces aside and takes the recording again.
    const fs::path after_reset = out_ / "hall" / (name + "-reset1.csv");
    if (fs::exists(after_reset))
      throw std::runtime_error(csv.string() + ": the Hall MCU reset during the recording (" +
                               std::to_string(r.counts.driver.resets) +
                               " reset(s) counted; MCU time restarted, the readings after it "
                               "are in " +
                               after_reset.filename().string() +
                               "): a Hall recording must be continuous; `msmcal resume` takes "
                               "it again");
    const dataset::HallRecording rec =
        interchange::ReadHallCsv(csv, acquisition::ClockCsvPathFor(csv));
    journal_->AppendHallReadings(name, rec.readings);
    journal_->AppendClockEdges(name, rec.clock_edges_us);
    journal_->SetMeta("hall." + name + ".present", "1");
    journal_->SetMeta("hall." + name + ".readings_dropped",
                      std::to_string(r.counts.readings_dropped));
    journal_->SetMeta("hall." + name + ".readings_lost",
                      std::to_string(r.counts.driver.readings_lost));
    SessionEvent e;
    e.kind = SessionEvent::Kind::kHallDone;
    e.recording = name;
    e.readings = r.counts.readings_delivered;
    e.edges = r.counts.edges_delivered;
    e.lost = r.counts.driver.readings_lost;
    e.dropped = r.counts.readings_dropped;
    e.text = "Hall: " + name + " " + std::to_string(e.readings) + " readings, " +
             std::to_string(e.edges) + " clock edges, " + std::to_string(e.lost) + " lost, " +
             std::to_string(e.dropped) + " dropped (recorder queue full) (" +
             acquisition::ToString(r.end) + ")";
    log_->Line(e.text, e.dropped > 0 ? "warning" : "info");
    Emit(e);
  }

  // A recording cut short before a resume is moved aside and taken again whole.
  void KeepPartial(const std::string& name) {
    for (const auto& f : KeepPartialHall(out_ / "hall", name)) {
      log_->Line("Hall: the " + name + " recording cut short before the resume is kept as " + f +
                     " and taken again",
                 "warning");
      result_.partial_hall_files.push_back(f);
    }
  }

  // --- State ---------------------------------------------------------------------------------
  const OrchestratorOptions& options_;
  const dataset::Recording& plan_;
  RigOperator& operator_;
  const ProgressFn& progress_;
  const fs::path out_;
  const store::SystemClock system_clock_;
  const store::Clock& clock_;
  SessionResult result_;
  // Frames in the journal (recorded before a resume or in this run), by plan file: true when
  // accepted. Each plan file is looked up once, before it is acquired.
  std::map<std::string, bool> recorded_;
  std::string background_device_;
  bool ask_background_later_ = false;
  FrameSignals playing_;
  double pattern_period_s_ = 0;
  // Declared in the order they are made; destroyed in reverse (the guard first).
  std::unique_ptr<store::SessionStore> journal_;
  std::unique_ptr<SessionLog> log_;
  std::unique_ptr<TranscriptFile> transcript_;
  OpenInstruments inst_;
  std::unique_ptr<gen::RigGenerators> rig_;
  std::unique_ptr<gen::Watchdog> watchdog_;
  std::optional<gen::WatchdogHandOver> handed_over_;
  std::mutex safe_state_mu_;  // the main thread's and the signal watcher's SafeState()
  std::unique_ptr<gen::SafeStateGuard> guard_;
};

}  // namespace

SessionResult RunSession(const OrchestratorOptions& options, const dataset::Recording& plan,
                         RigOperator& rig_operator, const ProgressFn& progress) {
  if (std::string e = options.Validate(); !e.empty()) throw std::invalid_argument(e);
  SessionController controller(options, plan, rig_operator, progress);
  return controller.Run();
}

}  // namespace msmcal::orchestrator
