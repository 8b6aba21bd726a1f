#include "app/session_flow.h"

#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "app/step_output.h"
#include "app/web_ui.h"
#include "common/text_io.h"
#include "drivers/generator/rig_config.h"
#include "drivers/hall_mcu/hall_mcu_config.h"
#include "mocks/mcu/mock_mcu.h"
#include "mocks/rig/truth_io.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/orchestrator/console_operator.h"
#include "sessions/orchestrator/fixed_rig_operator.h"
#include "sessions/orchestrator/hook_operator.h"
#include "sessions/orchestrator/preview.h"
#include "sessions/orchestrator/reference_steps.h"
#include "sessions/results/finish_steps.h"
#include "sessions/rig/rig_file.h"
#include "sessions/store/session_store.h"
#include "sessions/store/transfer.h"
#include "simulation/twin/demo_rig.h"

namespace msmcal::app {

namespace fs = std::filesystem;

namespace {

// What the guided modes show per gate decision: the live quality figures through `print`, and
// the annotated preview of every accepted frame under out/previews; after `before` (if any).
orchestrator::FrameObserver GuidedObserver(const fs::path& out, const dataset::BoardSpec& world,
                                           const dataset::BoardSpec& sliding,
                                           const orchestrator::ProgressFn& print,
                                           orchestrator::FrameObserver before) {
  auto live = orchestrator::MakeLiveFigures(print);
  auto previews = orchestrator::MakePreviewWriter(
      out, world, sliding, [print](const std::string& w) { print("warning: " + w); });
  return [before = std::move(before), live, previews](const orchestrator::FrameReport& r) {
    if (before) before(r);
    live(r);
    previews(r);
  };
}

// One --mock-fault of `msmcal demo` into the rig options (DemoAcquisitionOptions::mock_faults).
void AddMockFault(const std::string& text, twin::DemoRigOptions& ro) {
  const size_t colon = text.find(':');
  const std::string mock = text.substr(0, colon);
  const std::string spec = colon == std::string::npos ? std::string() : text.substr(colon + 1);
  if (mock == "camera" && spec.rfind("lost@", 0) == 0) {
    try {
      size_t used = 0;
      ro.camera_lost_after_frames = std::stoll(spec.substr(5), &used);
      if (used == spec.size() - 5 && ro.camera_lost_after_frames >= 0) return;
    } catch (const std::exception&) {
    }
    throw std::runtime_error("--mock-fault '" + text + "': expected camera:lost@N, N >= 0");
  }
  if (mock == "mcu-background") {
    ro.background_mcu_faults.push_back(sim::ParseMcuFault(spec));
  } else if (mock == "mcu-actual") {
    ro.actual_mcu_faults.push_back(sim::ParseMcuFault(spec));
  } else {
    throw std::runtime_error("--mock-fault '" + text +
                             "': expected camera:lost@N, mcu-background:SPEC or mcu-actual:SPEC");
  }
}

}  // namespace

namespace {

// The simulator's sliding-plate poses as the guided prompts' geometry.
std::vector<setup::PoseGeometry> SimPoses(const sim::Step1Options& s1) {
  std::vector<setup::PoseGeometry> poses;
  for (int l = 0; l < s1.poses; ++l) {
    const double mm =
        s1.nearest_mm + (s1.poses > 1 ? l * (s1.farthest_mm - s1.nearest_mm) / (s1.poses - 1) : 0);
    poses.push_back({mm, (l % 2 == 0 ? 1 : -1) * s1.tilt_deg});
  }
  return poses;
}

}  // namespace

void MakeGuidedWeb(DemoAcquisitionOptions& acq, WebUi* web) {
  MakeGuided(acq);
  const std::vector<setup::PoseGeometry> poses = SimPoses(acq.sim.step1);
  acq.make_operator = [web, poses](orchestrator::RigOperator& world,
                                   const dataset::Recording& plan) {
    live_view::WebOperatorOptions wo;
    wo.poses = poses;
    return web->MakeOperator(wo, &world);
  };
  auto guided = std::move(acq.adjust_options);
  acq.adjust_options = [web, guided](orchestrator::OrchestratorOptions& o) {
    guided(o);
    web->Observe(o);
  };
  acq.before_run = [web](const dataset::Recording& plan, const fs::path& out) {
    web->Start(plan, out);
  };
}

void MakeGuided(DemoAcquisitionOptions& acq) {
  const std::vector<setup::PoseGeometry> poses = SimPoses(acq.sim.step1);
  acq.make_operator = [poses](orchestrator::RigOperator& world, const dataset::Recording& plan) {
    orchestrator::ConsoleOperatorOptions co;
    co.input_fd = STDIN_FILENO;
    co.output_fd = STDOUT_FILENO;
    co.poses = poses;
    return std::make_unique<orchestrator::ConsoleOperator>(plan, co, &world);
  };
  const dataset::BoardSpec world{acq.sim.world_board.cols, acq.sim.world_board.rows,
                                 acq.sim.world_board.square_mm};
  const dataset::BoardSpec sliding{acq.sim.sliding_board.cols, acq.sim.sliding_board.rows,
                                   acq.sim.sliding_board.square_mm};
  acq.adjust_options = [world, sliding](orchestrator::OrchestratorOptions& o) {
    auto print = [](const std::string& line) {
      std::printf("%s\n", line.c_str());
      std::fflush(stdout);
    };
    o.on_frame = GuidedObserver(o.out_dir, world, sliding, print, o.on_frame);
  };
}

orchestrator::SessionResult RunDemoAcquisition(const fs::path& out,
                                               const DemoAcquisitionOptions& options) {
  twin::DemoRigOptions ro;
  ro.sim = options.sim;
  ro.camera_address = options.camera_address;
  ro.camera_frame_rate_hz = options.camera_frame_rate_hz;
  ro.external_generator_port1 = options.external_generator_port1;
  ro.external_generator_port2 = options.external_generator_port2;
  for (const std::string& f : options.mock_faults) AddMockFault(f, ro);
  twin::DemoRig rig(ro);
  if (options.progress) {
    for (const auto& w : rig.sim().warnings()) options.progress("simulator warning: " + w);
    char buf[200];
    std::snprintf(buf, sizeof(buf),
                  "demo rig: generators on ports %d and %d, camera %dx%d on %s; %zu step-1 and "
                  "%zu step-2 frames, %zu triggers",
                  rig.generators_port(1), rig.generators_port(2), rig.sim().camera().width,
                  rig.sim().camera().height, options.camera_address.c_str(),
                  rig.sim().step1_frames().size(), rig.sim().step2_frames().size(),
                  rig.sim().triggers().size());
    options.progress(buf);
  }
  orchestrator::OrchestratorOptions oo = rig.MakeOrchestratorOptions(out);
  oo.run_kind = "demo";
  oo.run_config_yaml = sim::SimOptionsToYaml(options.sim);
  oo.rig_id = "demo-rig (mock instruments)";
  oo.mirror_id = "simulated MSM, seed " + std::to_string(options.sim.seed);
  oo.note = options.note;
  oo.resume = options.resume;
  oo.watchdog = gen::SelfWatchdogLaunch("msmcal", "watchdog");
  if (options.adjust_options) options.adjust_options(oo);
  const dataset::Recording plan = rig.Plan();
  if (options.before_run) options.before_run(plan, out);
  std::unique_ptr<orchestrator::RigOperator> op;
  if (options.make_operator) op = options.make_operator(rig.world(), plan);
  orchestrator::RigOperator& who = op ? *op : rig.world();
  orchestrator::SessionResult result = orchestrator::RunSession(oo, plan, who, options.progress);
  sim::WriteTruth(out, sim::MakeTruth(rig.sim()));
  return result;
}

namespace {

std::string ReadTextFile(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file.string() + ": cannot read");
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

int64_t MonotonicNs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

int64_t RealtimeNs();

// The clock the camera driver stamps host arrival with: Aravis CLOCK_REALTIME
// (arv_buffer_get_system_timestamp), V4L2 CLOCK_MONOTONIC (the buffer timestamps).
std::function<int64_t()> HostClockFor(const std::string& camera) {
  const bool v4l2 = camera.rfind("v4l2:", 0) == 0 || camera.rfind("/dev/", 0) == 0;
  return v4l2 ? std::function<int64_t()>(MonotonicNs) : std::function<int64_t()>(RealtimeNs);
}

int64_t RealtimeNs() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace

dataset::Recording ReadPlanFolder(const fs::path& dir) {
  dataset::Recording plan;
  interchange::ParseSessionYaml(ReadTextFile(dir / "session.yaml"), (dir / "session.yaml").string(),
                                &plan);
  plan.camera = interchange::ParseCameraYaml(ReadTextFile(dir / "camera.yaml"),
                                             (dir / "camera.yaml").string());
  if (std::string e = interchange::CheckRecording(plan); !e.empty())
    throw std::runtime_error(dir.string() + ": plan: " + e);
  if (plan.triggers.empty())
    throw std::runtime_error((dir / "session.yaml").string() +
                             ": triggers: the plan has no trigger table (the laser would never "
                             "fire in step 2)");
  return plan;
}

orchestrator::SessionResult RunLabAcquisition(const fs::path& out,
                                              const LabAcquisitionOptions& options) {
  orchestrator::OrchestratorOptions oo;
  oo.out_dir = out;
  // The rig file's text, parsed once (journalled with the session, so `msmcal resume` reads
  // the same): generators, Hall MCU, and where the gate counts the dots (the plate's and the
  // screen's dot_margin_squares).
  const rig::RigFile rf = rig::ParseRigFile(options.rig_yaml, options.rig_origin);
  oo.generators = rf.generators;
  const hall_mcu::HallMcuConfig& mcu = rf.hall_mcu;
  oo.gate.step1_margin_squares = rf.sliding_plate.dot_margin_squares;
  oo.gate.step2_margin_squares = rf.step2.dot_margin_squares;
  oo.mcu = mcu.link;
  if (!options.mcu_device.empty()) oo.mcu.device = options.mcu_device;
  oo.mcu_rate_hz = mcu.rate_hz;
  oo.camera = options.camera_address;
  oo.camera_frame_rate_hz = options.camera_frame_rate_hz;
  oo.camera_exposure_us = options.camera_exposure_us;
  oo.background_seconds = options.background_seconds;
  oo.actual_min_seconds = options.actual_min_seconds;
  oo.run_kind = "lab";
  const std::string hook = ParseOperatorSpec(options.operator_spec);
  YAML::Emitter config;
  config << YAML::BeginMap << YAML::Key << "rig_file" << YAML::Value << options.rig_origin
         << YAML::Key << "camera_address" << YAML::Value << options.camera_address << YAML::Key
         << "mcu_device" << YAML::Value << oo.mcu.device << YAML::Key << "camera_frame_rate_hz"
         << YAML::Value << common::ShortestDouble(options.camera_frame_rate_hz);
  if (options.camera_exposure_us)
    config << YAML::Key << "camera_exposure_us" << YAML::Value
           << common::ShortestDouble(*options.camera_exposure_us);
  config << YAML::Key << "background_seconds" << YAML::Value
         << common::ShortestDouble(options.background_seconds) << YAML::Key << "actual_min_seconds"
         << YAML::Value << common::ShortestDouble(options.actual_min_seconds) << YAML::Key
         << "operator" << YAML::Value << options.operator_spec << YAML::Key << "hook_timeout_ms"
         << YAML::Value << options.hook_timeout_ms << YAML::Key << "poses" << YAML::Value
         << YAML::Flow << YAML::BeginSeq;
  for (const auto& p : options.poses)
    config << YAML::Flow << YAML::BeginSeq << common::ShortestDouble(p.distance_mm)
           << common::ShortestDouble(p.tilt_deg) << YAML::EndSeq;
  config << YAML::EndSeq;
  if (!options.reference.empty())
    config << YAML::Key << "reference" << YAML::Value << options.reference.string();
  config << YAML::Key << "rig_yaml" << YAML::Value << YAML::Literal << options.rig_yaml
         << YAML::EndMap;
  oo.run_config_yaml = std::string(config.c_str()) + "\n";
  oo.rig_id = options.rig_id;
  oo.mirror_id = options.mirror_id;
  oo.note = options.note;
  oo.resume = options.resume;
  oo.watchdog = gen::SelfWatchdogLaunch("msmcal", "watchdog");
  if (options.adjust_options) options.adjust_options(oo);
  if (std::string e = oo.Validate(); !e.empty()) throw std::invalid_argument(e);
  if (options.reference.empty())
    oo.on_frame = GuidedObserver(out, options.plan.world_board, options.plan.sliding_board,
                                 options.progress, oo.on_frame);

  // Frames count once they reached the host one exposure + one frame period (the transfer of a
  // free-running camera) + 100 ms after the set-up took effect: frames in flight are discarded.
  const int64_t settle_ns =
      std::max<int64_t>(300'000'000, std::llround((oo.camera_exposure_us.value_or(0) * 1e3) +
                                                  1e9 / oo.camera_frame_rate_hz + 100e6));
  // And their exposure began after it on the camera's clock (a frame delivered late by a loaded
  // host fails however late it arrives): the exposure, or the frame period it cannot exceed.
  const int64_t exposure_ns = std::llround(oo.camera_exposure_us ? *oo.camera_exposure_us * 1e3
                                                                 : 1e9 / oo.camera_frame_rate_hz);
  if (!options.reference.empty()) {  // a rig sweep's point: starts at the rig check, step 2 next
    if (!options.resume)
      orchestrator::SeedSessionFromReference(oo, options.plan, options.reference);
    oo.resume = true;
    orchestrator::FixedRigOptions fo;
    fo.mcu_device = oo.mcu.device;
    fo.host_clock_ns = HostClockFor(oo.camera);
    fo.settle_ns = settle_ns;
    fo.exposure_ns = exposure_ns;
    orchestrator::FixedRigOperator op(options.plan, fo);
    orchestrator::SessionResult result =
        orchestrator::RunSession(oo, options.plan, op, options.progress);
    if (!hook.empty()) (void)SendTruthRequest(hook, options.hook_timeout_ms, out, options.progress);
    return result;
  }
  if (!hook.empty()) {
    orchestrator::HookOperatorOptions ho;
    ho.settle_ns = settle_ns;
    ho.exposure_ns = exposure_ns;
    ho.command = hook;
    ho.timeout_ms = options.hook_timeout_ms;
    ho.poses = options.poses;
    ho.mcu_device = oo.mcu.device;
    ho.host_clock_ns = HostClockFor(oo.camera);
    ho.log = options.progress;
    orchestrator::HookOperator op(options.plan, ho, nullptr);
    orchestrator::SessionResult result =
        orchestrator::RunSession(oo, options.plan, op, options.progress);
    SendTruthRequest(op, out, options.progress);
    return result;
  }
  orchestrator::ConsoleOperatorOptions co;
  co.settle_ns = settle_ns;
  co.exposure_ns = exposure_ns;
  co.input_fd = options.input_fd;
  co.output_fd = options.output_fd;
  co.mcu_device = oo.mcu.device;
  co.host_clock_ns = HostClockFor(oo.camera);
  co.poses = options.poses;
  if (options.web) {
    options.web->Start(options.plan, out, oo.gate);
    options.web->Observe(oo);
    live_view::WebOperatorOptions wo;
    wo.mcu_device = co.mcu_device;
    wo.host_clock_ns = co.host_clock_ns;
    wo.settle_ns = co.settle_ns;
    wo.exposure_ns = exposure_ns;
    wo.poses = co.poses;
    const auto web_operator = options.web->MakeOperator(wo, nullptr);
    return orchestrator::RunSession(oo, options.plan, *web_operator, options.progress);
  }
  orchestrator::ConsoleOperator console(options.plan, co, nullptr);
  return orchestrator::RunSession(oo, options.plan, console, options.progress);
}

std::string ParseOperatorSpec(const std::string& spec) {
  if (spec == "console") return {};
  if (spec.rfind("hook:", 0) == 0 && spec.size() > 5) return spec.substr(5);
  throw std::invalid_argument("--operator = '" + spec +
                              "': must be console or hook:CMD (CMD non-empty)");
}

void SendTruthRequest(orchestrator::HookOperator& hook, const fs::path& out,
                      const orchestrator::ProgressFn& progress) {
  try {
    hook.RequestTruth(out / "truth");
  } catch (const orchestrator::HookFailed& e) {
    // The session is complete; a hook without truth to give is told to exit 0 (docs/lab-path.md).
    if (progress) progress(std::string("warning: ") + e.what());
  }
}

bool SendTruthRequest(const std::string& hook_command, int timeout_ms, const fs::path& out,
                      const orchestrator::ProgressFn& progress) {
  std::string outcome;
  bool ok = false;
  try {
    const int status = orchestrator::RunHookCommand(
        hook_command, setup::TruthRequestJson(out / "truth") + "\n", timeout_ms);
    ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
    outcome = orchestrator::DescribeWaitStatus(status);
  } catch (const orchestrator::HookFailed& e) {
    outcome = e.what();
  }
  if (progress)
    progress(ok ? "hook: truth request: " + outcome
                : "warning: operator hook '" + hook_command +
                      "' failed at the truth request: " + outcome);
  return ok;
}

LabAcquisitionOptions LabOptionsFromJournal(const fs::path& dir, const std::string& config_yaml) {
  const std::string where = (dir / "session.db").string() + " [config_yaml]";
  LabAcquisitionOptions o;
  try {
    const YAML::Node n = YAML::Load(config_yaml);
    o.rig_origin = n["rig_file"].as<std::string>();
    o.camera_address = n["camera_address"].as<std::string>();
    o.mcu_device = n["mcu_device"].as<std::string>();
    o.camera_frame_rate_hz = n["camera_frame_rate_hz"].as<double>();
    o.rig_yaml = n["rig_yaml"].as<std::string>();
    if (n["camera_exposure_us"]) o.camera_exposure_us = n["camera_exposure_us"].as<double>();
    if (n["background_seconds"]) o.background_seconds = n["background_seconds"].as<double>();
    if (n["actual_min_seconds"]) o.actual_min_seconds = n["actual_min_seconds"].as<double>();
    if (n["operator"]) o.operator_spec = n["operator"].as<std::string>();
    if (n["hook_timeout_ms"]) {  // journals before session 26 have none: the default
      o.hook_timeout_ms = n["hook_timeout_ms"].as<int>();
      if (o.hook_timeout_ms <= 0 || o.hook_timeout_ms > 86'400'000)
        throw std::runtime_error(where + ": hook_timeout_ms = " +
                                 std::to_string(o.hook_timeout_ms) + ": expected 1..86400000");
    }
    if (n["reference"]) o.reference = n["reference"].as<std::string>();
    if (n["poses"])
      for (const auto& p : n["poses"]) o.poses.push_back({p[0].as<double>(), p[1].as<double>()});
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(where + ": not a lab session configuration: " + e.what());
  }
  return o;
}

namespace {

// Single-quotes `s` as /bin/sh would need it: the steps are announced as the commands that run
// them on their own ("msmcal solve '/data/s 1' --threads 2").
std::string ShellQuote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// Runs one finish step in-process. With `echo`, prints "$ msmcal <command>" and the step's report
// as the command would; otherwise both go to `log_file`. Appends "msmcal <command>: ok" or
// "msmcal <command>: FAILED: <error>" to `notes` (if given). True when the step succeeded.
template <typename Step>
bool RunStep(const std::string& command, std::vector<std::string>* notes, bool echo,
             const fs::path& log_file, Step step) {
  if (echo) {
    std::printf("\n$ msmcal %s\n", command.c_str());
    std::fflush(stdout);
  } else if (std::FILE* f = std::fopen(log_file.c_str(), "a")) {
    std::fprintf(f, "$ msmcal %s\n", command.c_str());
    std::fclose(f);
  }
  const results::StepReport report = step();
  if (echo) {
    PrintStepReport(report);
    if (!report.ok()) spdlog::error("{}", report.error);
  } else {
    AppendStepReport(report, log_file);
  }
  if (notes)
    notes->push_back("msmcal " + command +
                     (report.ok() ? std::string(": ok") : ": FAILED: " + report.error));
  return report.ok();
}

}  // namespace

FinishResult FinishSession(const fs::path& dir, const FinishOptions& options,
                           std::vector<std::string>* notes) {
  FinishResult r;
  const fs::path results = dir / "results";
  const fs::path log = dir / "finish_log.txt";  // the steps' output when not echoed
  const std::string d = ShellQuote(dir.string());
  std::unique_ptr<store::SessionStore> journal;
  const store::SystemClock clock;
  if (fs::exists(dir / store::kSessionDbName)) journal = store::SessionStore::Open(dir, clock);
  auto step = [&](const char* name, store::StepState state) {
    if (journal) journal->SetStep(name, state);
  };
  auto skip = [&](const fs::path& output, const char* what) {
    if (!options.skip_done || !fs::exists(output)) return false;
    if (options.echo) std::printf("%s: already done (%s exists)\n", what, output.c_str());
    if (notes) notes->push_back(std::string(what) + ": already done");
    return true;
  };

  r.solved = skip(results / "summary.json", "solve");
  if (!r.solved) {
    step("solve", store::StepState::kRunning);
    solver::PipelineOptions solve;  // as `msmcal solve DIR --threads N` has them
    solve.image_threads = options.threads;
    solve.mle.num_threads = 1;
    r.solved = RunStep("solve " + d + " --threads " + std::to_string(options.threads), notes,
                       options.echo, log, [&] { return results::RunSolveStep(dir, solve); });
    step("solve", r.solved ? store::StepState::kDone : store::StepState::kFailed);
  }
  if (r.solved) {
    r.hall_calibrated = skip(results / "hall_model.yaml", "hall calibrate");
    if (!r.hall_calibrated) {
      step("hall_calibration", store::StepState::kRunning);
      r.hall_calibrated = RunStep("hall calibrate " + d, notes, options.echo, log, [&] {
        return results::RunHallCalibration(dir, hall::HallCalibrationOptions{});
      });
      if (!r.hall_calibrated) step("hall_calibration", store::StepState::kFailed);
    }
    if (r.hall_calibrated) {
      r.hall_predicted = skip(results / "hall_poses.csv", "hall predict");
      const fs::path model = results / "hall_model.yaml", readings = dir / "hall" / "actual.csv",
                     poses = results / "hall_poses.csv";
      if (!r.hall_predicted)
        r.hall_predicted =
            RunStep("hall predict " + ShellQuote(model.string()) + " " +
                        ShellQuote(readings.string()) + " " + ShellQuote(poses.string()),
                    notes, options.echo, log,
                    [&] { return results::RunHallPrediction(model, readings, poses); });
      step("hall_calibration",
           r.hall_predicted ? store::StepState::kDone : store::StepState::kFailed);
    }
  } else if (options.echo) {
    std::printf("SKIPPED: Hall calibration (needs the solver's mirror poses)\n");
  }
  if (journal && fs::exists(results)) {
    store::PutResultsFromFolder(*journal, results);
    journal->AddEvent("info", std::string("results stored: solve ") + (r.solved ? "ok" : "failed") +
                                  ", hall calibration " +
                                  (r.hall_calibrated && r.hall_predicted ? "ok" : "not done"));
  }
  return r;
}

}  // namespace msmcal::app
