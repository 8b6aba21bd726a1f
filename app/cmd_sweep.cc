// `msmcal sweep PLAN.yaml --out DIR` / `msmcal sweep --resume DIR` (issue 9, sweep mode): one
// simulated calibration session per point of a YAML sweep plan (sessions/sweep/sweep_plan.h,
// docs/sweep.md), each on the demo rig through the real drivers and the orchestrator, then solved
// and Hall-calibrated (FinishSession), unattended: a failing point is recorded with its reason and
// the sweep goes on. Re-running the same command on an existing DIR continues the sweep: finished
// points are skipped, a point killed mid-acquisition is resumed from its journal (nothing
// recorded is taken again), a point killed while solving only finishes. Progress: one line per
// event (a redrawn status line on a terminal); at the end a summary table (also DIR/summary.csv).
//
// `msmcal sweep SWEEP.yaml --rig RIG --reference SESSION --out DIR [--operator hook:CMD]` (issue
// 20, docs/lab-path.md "Rig sweeps"): the same on the rig, each point the reference's step 1 and
// background Hall recording with the point's rig check, step 2 and actual Hall recording
// (RunLabAcquisition with LabAcquisitionOptions::reference: nobody at the rig), then the same
// finish steps; every point is checked against the rig's limits and the reference first.
#include <sys/ioctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/command_registry.h"
#include "app/rig_sweep_parameters.h"
#include "app/session_flow.h"
#include "drivers/generator/safe_state.h"
#include "mocks/rig/rig_simulator.h"
#include "mocks/rig/truth_io.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/orchestrator/fixed_rig_operator.h"
#include "sessions/orchestrator/hook_operator.h"
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/orchestrator/reference_steps.h"
#include "sessions/plan/session_plan.h"
#include "sessions/report/session_report.h"
#include "sessions/report/sweep_report.h"
#include "sessions/rig/rig_file.h"
#include "sessions/setup/setup.h"
#include "sessions/store/session_store.h"
#include "sessions/sweep/sweep_plan.h"
#include "sessions/sweep/sweep_runner.h"
#include "simulation/sweep_points/sim_sweep_parameters.h"
#include "simulation/truth/truth_comparison.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;

struct SweepArgs {
  std::string plan;
  std::string out;
  std::string resume;
  std::string rig;        // a rig sweep: the rig file whose fields the axes vary
  std::string reference;  // a rig sweep: the session whose step 1 every point reuses
  std::string operator_spec;
  std::string mcu;  // a rig sweep: the Hall MCU's device (empty: the rig file's)
  std::string camera_address = "127.0.0.1";
  bool camera_given = false;  // a rig sweep: --camera-address overrides the rig file's camera
  int hook_timeout_s = 600;
  bool hook_timeout_given = false;
  int threads = 2;
  bool list = false;
};

// Shortens a progress line to `width` characters: drops the elapsed time, abbreviates
// "rejected", then shortens the
// point's values ("[...]"), then elides the middle of the line.
std::string FitWidth(const std::string& line, size_t width) {
  std::string s = line;
  const size_t elapsed = s.find(" | elapsed ");
  if (s.size() > width && elapsed != std::string::npos) {
    const size_t next = s.find(" | ", elapsed + 3);
    if (next != std::string::npos) s.erase(elapsed, next - elapsed);
  }
  const size_t rejected = s.find(" rejected | ");
  if (s.size() > width && rejected != std::string::npos) s.replace(rejected, 9, " rej");
  const size_t open = s.find(" ["), close = s.find("] ");
  if (s.size() > width && open != std::string::npos && close != std::string::npos &&
      close > open + 2) {
    const size_t label = close - open - 2, excess = s.size() - width;
    const size_t keep = label > excess + 3 ? label - excess - 3 : 0;
    s = s.substr(0, open + 2 + keep) + "..." + s.substr(close);
  }
  if (s.size() <= width) return s;
  const size_t head = width / 3;
  return s.substr(0, head) + "..." + s.substr(s.size() - (width - head - 3));
}

// Prints progress lines: on a terminal, transient lines redraw one status line ('\r'); otherwise
// every line is printed as it comes (scripts and tests read them).
class ProgressPrinter {
 public:
  ProgressPrinter() : tty_(::isatty(::fileno(stdout)) == 1) {}
  void Print(const std::string& line, bool transient) {
    std::lock_guard<std::mutex> lock(mu_);
    if (tty_) {
      std::string shown = line;
      // A transient line must fit one terminal row, or '\r' cannot redraw it.
      winsize ws{};
      if (transient && ::ioctl(::fileno(stdout), TIOCGWINSZ, &ws) == 0 && ws.ws_col > 40)
        shown = FitWidth(line, static_cast<size_t>(ws.ws_col) - 1);
      const size_t shown_width = shown.size();
      if (shown.size() < width_) shown += std::string(width_ - shown.size(), ' ');
      std::printf("\r%s", shown.c_str());
      width_ = transient ? shown_width : 0;
      if (!transient) std::printf("\n");
    } else {
      std::printf("%s\n", line.c_str());
    }
    std::fflush(stdout);
  }
  // Ends a pending status line before other output.
  void Break() {
    std::lock_guard<std::mutex> lock(mu_);
    if (tty_ && width_ > 0) std::printf("\n");
    width_ = 0;
  }

 private:
  std::mutex mu_;
  bool tty_;
  size_t width_ = 0;
};

sweep::PointFolderState InspectPoint(const fs::path& folder) {
  sweep::PointFolderState s;
  s.folder_exists = fs::exists(folder);
  s.folder_empty = !s.folder_exists || fs::is_empty(folder);
  s.journal_exists = fs::exists(folder / store::kSessionDbName);
  if (s.journal_exists) {
    try {
      s.session_complete = orchestrator::ReadSessionJournal(folder).complete;
    } catch (const std::exception&) {
      s.session_complete = false;  // resume says what is wrong with it (the point fails)
    }
  }
  const fs::path results = folder / "results";
  s.results_complete = fs::exists(results / "summary.json") &&
                       fs::exists(results / "hall_model.yaml") &&
                       fs::exists(results / "hall_poses.csv");
  return s;
}

// The point's figures against the truth in its folder (a simulated point's simulator, or the
// twin's for a rig sweep on the twin), from the session report. Never throws.
void AugmentFromReport(const fs::path& folder, sweep::PointFigures* f) {
  if (!fs::exists(folder / "truth") || !fs::exists(folder / "results")) return;
  try {
    const report::SessionReport r = report::BuildSessionReport(
        folder, {/*session_process=*/true, {}}, simulation::SimTruthSource());
    if (r.have_planes) f->normal_rms_vs_truth_deg = r.normal_rms_vs_truth_deg;
    if (r.have_hall_vs_truth) {
      f->hall_vs_truth_alpha_deg = r.hall_rms_vs_truth[0];
      f->hall_vs_truth_beta_deg = r.hall_rms_vs_truth[1];
      f->hall_vs_truth_trans_mm = r.hall_rms_vs_truth[2];
    }
  } catch (const std::exception&) {
    // The summary never stops the sweep; the figures stay empty.
  }
}

// The steps after a point's acquisition, as `msmcal demo` / `session run` finish: solve, Hall
// calibration and prediction (skipping those done), then the point's report. "" or the reason.
std::string FinishPoint(const fs::path& folder, int threads) {
  FinishOptions fo;
  fo.skip_done = true;
  fo.echo = false;
  fo.threads = threads;
  std::vector<std::string> notes;
  const FinishResult r = FinishSession(folder, fo, &notes);
  try {
    (void)report::WriteSessionReport(folder, {/*session_process=*/true, notes},
                                     simulation::SimTruthSource());
  } catch (const std::exception& e) {
    if (r.ok()) return std::string("report: ") + e.what();
  }
  if (r.ok()) return "";
  for (const auto& n : notes)
    if (n.find("FAILED") != std::string::npos) return n;
  return r.solved ? "Hall calibration not done" : "solve not done";
}

// RunSweep with the progress printer and the injected clock, then the summary table, the
// sweep's report and the exit status (1 when a point failed).
void RunSweepAndReport(const sweep::SweepPlan& plan, const fs::path& dir, sweep::SweepHooks hooks,
                       ProgressPrinter& printer, std::chrono::steady_clock::time_point start) {
  hooks.now_s = [start] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  hooks.print = [&printer](const std::string& line, bool transient) {
    printer.Print(line, transient);
  };
  hooks.inspect = InspectPoint;
  hooks.augment = AugmentFromReport;
  const sweep::SweepOutcome outcome = sweep::RunSweep(plan, dir, hooks);
  printer.Break();
  std::printf("\nsweep summary (%s):\n%s", (dir / "summary.csv").string().c_str(),
              outcome.table.c_str());
  try {  // the sweep's report across its points (each point's own report is already written)
    (void)report::WriteSweepReport(dir, plan, sweep::ExpandPoints(plan),
                                   simulation::SimTruthSource(),
                                   /*write_point_reports=*/false, {/*session_process=*/true, {}});
    std::printf("sweep report: %s\n", (dir / "report.html").string().c_str());
  } catch (const std::exception& e) {
    std::printf("sweep report not written: %s\n", e.what());
  }
  std::printf("total %.1f s\n", hooks.now_s());
  std::fflush(stdout);
  if (outcome.failed > 0) throw CLI::RuntimeError(1);
}

// A point's rig file: the sweep's --rig with the point's values (resolved and checked by
// RigSweepParameters::Resolve when the points were expanded).
rig::RigFile PointRig(const sweep::SweepPoint& point, const std::string& rig_file) {
  return rig::ParseRigFile(point.options_yaml,
                           rig_file + " with the values of point " + point.name);
}

// `msmcal sweep SWEEP.yaml --rig RIG --reference SESSION --out DIR`: every point is checked
// against the rig's limits and its plan against the reference here, before any folder is made
// or any instrument contacted; then one session per point (docs/lab-path.md, "Rig sweeps"):
// the reference's step 1 and background Hall recording, the point's rig check, actual Hall
// recording and step 2 with nobody at the rig, solved and Hall-calibrated in this process.
void RunRigSweep(const SweepArgs& args, const fs::path& plan_file, const fs::path& dir) {
  if (fs::exists(dir / "sweep.yaml") && !IsRigSweepPlan(dir / "sweep.yaml"))
    throw std::runtime_error(dir.string() +
                             " holds a simulated sweep (its sweep.yaml's base: holds simulator "
                             "options): continue it without --rig, --reference, --mcu and "
                             "--operator");
  if (args.reference.empty() && !args.list)
    throw std::runtime_error(
        "sweep --rig: give --reference SESSION_DIR (the session whose step 1 "
        "every point reuses)");
  if (!args.reference.empty()) {
    const fs::path ref = args.reference;
    for (const char* f : {"session.yaml", "camera.yaml"})
      if (!fs::exists(ref / f))
        throw std::runtime_error("sweep --rig: --reference " + ref.string() + ": no " + f +
                                 " (not a complete session folder)");
    if (!fs::exists(ref / "hall" / "background.csv"))
      throw std::runtime_error("sweep --rig: --reference " + ref.string() +
                               ": no hall/background.csv (the background Hall recording)");
  }
  const std::string hook =
      args.operator_spec.empty() ? std::string() : ParseOperatorSpec(args.operator_spec);
  if (!args.operator_spec.empty() && hook.empty())
    throw std::invalid_argument("--operator = '" + args.operator_spec +
                                "': a rig sweep has nobody at the rig: hook:CMD (the set-up and "
                                "truth requests) or no --operator");
  const auto parameters = RigSweepParameters::FromRigFile(args.rig);
  const sweep::SweepPlan plan = sweep::LoadSweepPlan(plan_file, parameters);
  const std::vector<sweep::SweepPoint> points = sweep::ExpandPoints(plan);  // every point checked
  // Each point's plan: the reference's step 1 with the point's step 2 (checked here too).
  const fs::path reference = args.reference.empty() ? fs::path() : fs::absolute(args.reference);
  dataset::Recording reference_session;
  std::string reference_rig_id, reference_mirror_id;
  if (!reference.empty()) {
    try {
      reference_session = interchange::ReadRecordingForSolve(reference);
    } catch (const std::exception& e) {
      throw std::runtime_error("sweep --rig: --reference " + reference.string() + ": " + e.what());
    }
    const orchestrator::SessionJournalState j = orchestrator::ReadSessionJournal(reference);
    reference_rig_id = j.rig_id;
    reference_mirror_id = j.mirror_id;
  }
  std::map<std::string, dataset::Recording> point_plans;
  for (const auto& p : points) {
    if (reference.empty()) continue;
    try {
      point_plans[p.name] = orchestrator::PlanWithReferenceStep1(
          reference_session, "--reference " + reference.string(),
          plan::DesignSessionPlan(PointRig(p, args.rig)));
    } catch (const std::exception& e) {
      throw std::runtime_error(plan.source + ": point " + p.name + ": " + e.what());
    }
  }
  std::printf("msmcal sweep: %zu rig points (%zu axes x %d repeats) from %s into %s\n",
              points.size(), plan.axes.size(), plan.repeats, args.rig.c_str(),
              dir.string().c_str());
  for (const auto& p : points) std::printf("  %s  ok (within the rig's limits)\n", p.name.c_str());
  std::fflush(stdout);
  if (args.list) return;

  ProgressPrinter printer;
  const auto start = std::chrono::steady_clock::now();
  sweep::SweepHooks hooks;
  // The one state change of the sweep (MSM mounted, camera at C2, every beam unblocked), through
  // the hook before the first point acquired in this run (again after a restart: the hook's rig
  // may have been changed meanwhile).
  bool rig_in_state = hook.empty();
  hooks.acquire = [&](const sweep::SweepPoint& point, const fs::path& folder, bool resume,
                      const orchestrator::SessionEventObserver& on_event) {
    const rig::RigFile rig = PointRig(point, args.rig);
    const dataset::Recording& point_plan = point_plans.at(point.name);
    if (!rig_in_state) {
      const std::string json = setup::SetupToJson(orchestrator::FixedRigSetup(point_plan));
      const int status =
          orchestrator::RunHookCommand(hook, json + "\n", args.hook_timeout_s * 1000);
      const std::string outcome = orchestrator::DescribeWaitStatus(status);
      printer.Print(
          "hook: the sweep's rig state (MSM mounted, camera at C2, every beam "
          "unblocked): " +
              outcome,
          /*transient=*/false);
      if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0))
        throw std::runtime_error("operator hook '" + hook +
                                 "' failed at the sweep's rig state: " + outcome);
      rig_in_state = true;
    }
    LabAcquisitionOptions lab;
    lab.rig_yaml = rig.text;
    lab.rig_origin = args.rig + " with the values of point " + point.name;
    lab.camera_address = args.camera_given ? args.camera_address : rig.camera.OpenString();
    lab.mcu_device = args.mcu;
    lab.camera_frame_rate_hz = rig.camera.frame_rate_hz;
    lab.camera_exposure_us = rig.camera.exposure_us;
    lab.background_seconds = rig.step2.hall_background_s;
    lab.actual_min_seconds = rig.step2.hall_actual_min_s;
    lab.poses = plan::PoseGeometryOf(rig);
    lab.operator_spec = hook.empty() ? "console" : args.operator_spec;
    lab.hook_timeout_ms = args.hook_timeout_s * 1000;
    lab.plan = point_plan;
    lab.reference = reference;
    lab.resume = resume;
    lab.rig_id = reference_rig_id;
    lab.mirror_id = reference_mirror_id;
    lab.note = "msmcal sweep point " + point.name + " (" + point.Label() + ")";
    lab.adjust_options = [on_event](orchestrator::OrchestratorOptions& o) {
      o.on_event = on_event;
    };
    (void)RunLabAcquisition(folder, lab);
  };
  hooks.finish = [&](const sweep::SweepPoint& point, const fs::path& folder) -> std::string {
    // Killed between the end of the acquisition and the truth request: ask now (nothing was
    // applied to the generators since: the hook's truth is still this point's drive).
    if (!hook.empty() && !fs::exists(folder / "truth"))
      (void)SendTruthRequest(hook, args.hook_timeout_s * 1000, folder, nullptr);
    (void)point;
    return FinishPoint(folder, args.threads);
  };
  RunSweepAndReport(plan, dir, std::move(hooks), printer, start);
}

void RunSweepCommand(const SweepArgs& args) {
  if (!args.resume.empty() && (!args.plan.empty() || !args.out.empty()))
    throw std::runtime_error("sweep: give either PLAN.yaml --out DIR or --resume DIR, not both");
  if (args.resume.empty() && (args.plan.empty() || args.out.empty()))
    throw std::runtime_error("sweep: give PLAN.yaml and --out DIR (or --resume DIR)");
  const fs::path dir = fs::absolute(args.resume.empty() ? args.out : args.resume);
  fs::path plan_file = args.plan;
  if (!args.resume.empty()) {
    plan_file = dir / "sweep.yaml";
    if (!fs::exists(plan_file))
      throw std::runtime_error(dir.string() + ": no sweep.yaml here: not a sweep folder");
  }
  if (!args.rig.empty()) {
    RunRigSweep(args, plan_file, dir);
    return;
  }
  if (!args.reference.empty() || !args.operator_spec.empty() || !args.mcu.empty() ||
      args.hook_timeout_given)
    throw std::runtime_error(
        "sweep: --reference, --operator, --mcu and --hook-timeout are for a rig sweep (--rig "
        "RIG)");
  if (fs::exists(dir / "sweep.yaml") && IsRigSweepPlan(dir / "sweep.yaml"))
    throw std::runtime_error(dir.string() +
                             " holds a rig sweep (its sweep.yaml's base: is a rig file): continue "
                             "it with `msmcal sweep --resume DIR --rig RIG --reference "
                             "SESSION_DIR` and the first run's --mcu and --operator "
                             "(docs/lab-path.md, \"Rig sweeps\")");
  const sweep::SweepPlan plan = sweep::LoadSweepPlan(plan_file, simulation::SimSweepParameters());
  const std::vector<sweep::SweepPoint> points = sweep::ExpandPoints(plan);
  std::printf("msmcal sweep: %zu points (%zu axes x %d repeats) into %s\n", points.size(),
              plan.axes.size(), plan.repeats, dir.string().c_str());
  if (args.list) {
    for (const auto& p : points)
      std::printf("  %s  seed %llu\n", p.name.c_str(), static_cast<unsigned long long>(p.seed));
    return;
  }
  std::fflush(stdout);

  ProgressPrinter printer;
  const auto start = std::chrono::steady_clock::now();
  sweep::SweepHooks hooks;
  hooks.acquire = [&args](const sweep::SweepPoint& point, const fs::path& folder, bool resume,
                          const orchestrator::SessionEventObserver& on_event) {
    DemoAcquisitionOptions acq;
    acq.sim = simulation::PointSimOptions(point);
    acq.camera_address = args.camera_address;
    acq.resume = resume;
    acq.adjust_options = [on_event](orchestrator::OrchestratorOptions& o) {
      o.on_event = on_event;
    };
    acq.note = "msmcal sweep point " + point.name;
    (void)RunDemoAcquisition(folder, acq);
  };
  hooks.finish = [&args](const sweep::SweepPoint& point, const fs::path& folder) -> std::string {
    // Killed between the end of the acquisition and the truth being written: write it now (the
    // simulator is deterministic in its options).
    if (!fs::exists(folder / "truth"))
      sim::WriteTruth(folder,
                      sim::MakeTruth(sim::RigSimulator(simulation::PointSimOptions(point))));
    return FinishPoint(folder, args.threads);
  };
  RunSweepAndReport(plan, dir, std::move(hooks), printer, start);
}

void AddSweepCommands(CLI::App& app) {
  auto args = std::make_shared<SweepArgs>();
  auto* cmd = app.add_subcommand(
      "sweep",
      "Run one calibration session per point of a YAML sweep plan (simulated, or with --rig "
      "on the rig: step 2 per point, the reference's step 1), unattended and resumable (re-run "
      "the same command, or --resume DIR, to continue)");
  cmd->add_option("PLAN", args->plan, "Sweep plan (docs/sweep.md, config/sweep-example.yaml)");
  cmd->add_option("--out", args->out,
                  "Sweep folder: created, or continued when it holds the same sweep");
  cmd->add_option("--resume", args->resume, "Continue the sweep in this folder (its sweep.yaml)");
  auto* camera = cmd->add_option("--camera-address", args->camera_address,
                                 "Address the mock GigE Vision camera serves on (port 3956); a "
                                 "rig sweep: the camera (default: the rig file's)");
  cmd->add_option("--threads", args->threads, "Solver threads per point")->check(CLI::Range(1, 64));
  cmd->add_flag("--list", args->list, "List the points and their folder names, run nothing");
  cmd->add_option("--rig", args->rig,
                  "A rig sweep: the axes vary this rig file's fields (docs/lab-path.md, Rig "
                  "sweeps); every point is checked against its limits first");
  cmd->add_option("--reference", args->reference,
                  "A rig sweep: the session folder whose step 1 every point reuses");
  cmd->add_option("--operator", args->operator_spec,
                  "A rig sweep: hook:CMD receives the sweep's one set-up (MSM mounted, camera at "
                  "C2) and each point's truth request (nobody at the rig)");
  cmd->add_option("--mcu", args->mcu,
                  "A rig sweep: Hall MCU serial device (default: the rig file's hall_mcu.device; "
                  "on the twin its --hall-link)");
  auto* hook_timeout = cmd->add_option("--hook-timeout", args->hook_timeout_s,
                                       "A rig sweep: seconds a hook may take per call")
                           ->check(CLI::Range(1, 86400));
  cmd->callback([args, camera, hook_timeout] {
    const gen::OpenGeneratorsGuard signals;  // from the start: docs/watchdog.md
    args->camera_given = camera->count() > 0;
    args->hook_timeout_given = hook_timeout->count() > 0;
    RunSweepCommand(*args);
  });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/9, AddSweepCommands);

}  // namespace msmcal::app
