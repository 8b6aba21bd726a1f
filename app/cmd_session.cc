// `msmcal session check --rig FILE [--camera ADDR] [--mcu DEVICE]`: the orchestrator's rig check
// against the instruments of a rig configuration (config/rig.yaml: `generators:` and `hall_mcu:`
// sections): identifies both generators and checks the reference lock and the signal limits,
// opens the camera (GigE Vision by address, or V4L2 by device; Mono8), identifies the Hall MCU and
// reads a status frame. Prints what it found and, when something is wrong, the list of problems
// (exit status 1). Generator outputs are left off.
//
// `msmcal session run --rig FILE --plan DIR --out DIR [--operator console|hook:CMD] [--dry-run]
// [--camera ADDR] [--mcu DEVICE] [--frame-rate HZ] [--hook-timeout S] [--rig-id ID]
// [--mirror-id ID] [--note TEXT]`: a calibration session on the real rig (docs/lab-path.md). The
// rig file (docs/rig-file.md) is loaded and validated and the plan checked against it before
// anything is created or contacted; the camera comes from its camera section (GigE address or
// V4L2 device) unless --camera overrides it. The person at the rig is guided on this terminal
// (console: one prompt per physical set-up, live quality figures, annotated previews in
// DIR/previews) or a hook program gets each set-up as JSON on stdin (hook:CMD). Journalled in
// DIR/session.db, then solved and the Hall sensor calibrated. The plan folder holds session.yaml
// and camera.yaml as the interchange format defines them (`msmcal plan` writes one). --dry-run
// checks the plan against the rig's limits and the free disk and prints the expected duration,
// prompts and disk needed, creating nothing. Interrupted, it continues with `msmcal resume DIR`.
// `--ui web[:PORT]`: the operator answers on the live view's page in a browser instead of the
// console (app/web_ui.h; docs/guided.md).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "app/command_registry.h"
#include "app/session_flow.h"
#include "app/web_ui.h"
#include "common/yaml_fields.h"
#include "drivers/generator/rig_config.h"
#include "drivers/generator/safe_state.h"
#include "drivers/hall_mcu/hall_mcu_config.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/plan/session_plan.h"
#include "sessions/report/session_report.h"
#include "sessions/rig/rig_file.h"
#include "simulation/truth/truth_comparison.h"

namespace msmcal::app {
namespace {

struct SessionCheckArgs {
  std::string rig = "config/rig.yaml";
  std::string camera;
  std::string mcu;
};

void RunSessionCheck(const SessionCheckArgs& args) {
  orchestrator::OrchestratorOptions options;
  options.out_dir = "unused";
  options.generators = gen::LoadRigGeneratorConfig(args.rig);
  if (std::string e = options.generators.Validate(); !e.empty())
    throw std::runtime_error(args.rig + ": " + e);
  const hall_mcu::HallMcuConfig mcu = hall_mcu::LoadHallMcuConfig(args.rig);
  options.mcu = mcu.link;
  options.mcu_rate_hz = mcu.rate_hz;
  // --camera overrides the rig file's camera section (a rig file without one needs --camera).
  options.camera =
      args.camera.empty() ? rig::LoadRigFile(args.rig).camera.OpenString() : args.camera;
  const std::string device = args.mcu.empty() ? mcu.link.device : args.mcu;
  const orchestrator::RigCheckResult r = orchestrator::CheckRigOnly(options, nullptr, device);
  for (const auto& f : r.found) std::printf("ok: %s\n", f.c_str());
  if (!r.ok) {
    std::printf("rig check FAILED (%zu problems):\n", r.problems.size());
    for (const auto& p : r.problems) std::printf("  - %s\n", p.c_str());
    throw CLI::RuntimeError(1);
  }
  std::printf("rig check passed; generator outputs are off\n");
}

struct SessionRunArgs {
  std::string rig = "config/rig.yaml";
  std::string camera;  // empty: the rig file's camera section
  std::string mcu;
  std::string plan;
  std::string out;
  std::string rig_id, mirror_id, note;
  double frame_rate_hz = 0;  // with frame_rate_given: instead of the rig file's
  bool frame_rate_given = false;
  std::string operator_spec = "console";
  int hook_timeout_s = 600;
  bool dry_run = false;
  WebUiArgs web;  // --ui web[:PORT], --ui-bind
};

// The nearest existing folder at or above `p` (where DIR would be created).
std::filesystem::path ExistingAncestor(std::filesystem::path p) {
  while (!p.empty() && !std::filesystem::exists(p)) p = p.parent_path();
  return p.empty() ? std::filesystem::current_path() : p;
}

// --dry-run: the plan against the rig's limits and the free disk; touches nothing.
void RehearseSession(const SessionRunArgs& args, const rig::RigFile& rig,
                     const dataset::Recording& plan, const std::filesystem::path& out) {
  const plan::PlanSummary s = plan::SummarisePlan(plan, rig);
  const std::filesystem::path parent = ExistingAncestor(out.parent_path());
  const std::filesystem::space_info space = std::filesystem::space(parent);
  std::printf("dry run: %s against %s (no instrument contacted, %s not created)\n%s",
              args.plan.c_str(), args.rig.c_str(), out.c_str(), s.text.c_str());
  std::printf("free disk at %s: %.1f GiB\n", parent.c_str(),
              static_cast<double>(space.available) / (1ull << 30));
  if (space.available < s.disk_bytes) {
    throw std::runtime_error("dry run: disk needed = " + std::to_string(s.disk_bytes) +
                             " bytes exceeds the free space at " + parent.string() + " (" +
                             std::to_string(space.available) + " bytes)");
  }
  std::printf("dry run: the plan fits the rig's limits\n");
}

void RunSessionRun(const SessionRunArgs& args) {
  namespace fs = std::filesystem;
  const auto start = std::chrono::steady_clock::now();
  std::unique_ptr<WebUi> web;  // --ui checked before any file is read
  if (args.web.enabled()) web = std::make_unique<WebUi>(args.web);
  const fs::path out = fs::absolute(args.out);
  // Everything is checked before anything is created or contacted.
  rig::RigFile rig = rig::LoadRigFile(args.rig);
  if (args.frame_rate_given) {  // the rig file's rule, so that --dry-run and the plan see it too
    if (const std::string e = rig.camera.CheckFrameRate(args.frame_rate_hz); !e.empty())
      throw std::invalid_argument("--frame-rate = " + common::FieldNumber(args.frame_rate_hz) +
                                  ": " + e + " (" + args.rig + ")");
    rig.camera.frame_rate_hz = args.frame_rate_hz;
  }
  if (!ParseOperatorSpec(args.operator_spec).empty() && web)
    throw std::invalid_argument("--ui web and --operator " + args.operator_spec +
                                ": the web page is an operator; use one of them");
  if (args.hook_timeout_s <= 0 || args.hook_timeout_s > 86400)  // as `msmcal sweep`'s
    throw std::invalid_argument("--hook-timeout = " + std::to_string(args.hook_timeout_s) +
                                ": must be in (0, 86400] s");
  const dataset::Recording plan = ReadPlanFolder(args.plan);
  if (std::string e = plan::CheckPlanAgainstRig(plan, rig); !e.empty())
    throw std::runtime_error(args.plan + " against " + args.rig + ": " + e);
  if (fs::exists(out) && !fs::is_empty(out))
    throw std::runtime_error(out.string() +
                             ": exists and is not empty (an interrupted session continues with "
                             "`msmcal resume " +
                             out.string() + "`)");
  if (args.dry_run) {
    RehearseSession(args, rig, plan, out);
    return;
  }
  LabAcquisitionOptions lab;
  lab.rig_yaml = rig.text;
  lab.rig_origin = args.rig;
  lab.camera_address = args.camera.empty() ? rig.camera.OpenString() : args.camera;
  lab.mcu_device = args.mcu;
  lab.camera_frame_rate_hz = rig.camera.frame_rate_hz;  // --frame-rate applied above
  lab.camera_exposure_us = rig.camera.exposure_us;
  lab.background_seconds = rig.step2.hall_background_s;
  lab.actual_min_seconds = rig.step2.hall_actual_min_s;
  lab.poses = plan::PoseGeometryOf(rig);
  lab.operator_spec = args.operator_spec;
  lab.hook_timeout_ms = args.hook_timeout_s * 1000;
  lab.plan = plan;
  lab.rig_id = args.rig_id;
  lab.mirror_id = args.mirror_id;
  lab.note = args.note;
  lab.web = web.get();
  std::vector<std::string> notes;
  lab.progress = [&](const std::string& line) {
    const double t =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("[%6.1f s] %s\n", t, line.c_str());
    std::fflush(stdout);
    notes.push_back(line);
    if (web) web->AddLogLine(line);
  };
  try {
    (void)RunLabAcquisition(out, lab);
  } catch (const std::exception& e) {
    if (web) web->Finished(/*done=*/false, e.what());
    throw;
  }
  if (web) web->Finished(/*done=*/true, "acquisition complete: solving, then the report");
  const FinishResult finished = FinishSession(out, FinishOptions{}, &notes);
  const report::SessionReport report = report::WriteSessionReport(
      out, {/*session_process=*/true, notes}, simulation::SimTruthSource());
  std::printf("\n%s\nreport: %s\n", report.text.c_str(), (out / "report.html").string().c_str());
  if (!finished.ok()) throw CLI::RuntimeError(1);
}

void AddSessionCommands(CLI::App& app) {
  CLI::App* session = GetOrAddSubcommand(app, "session", "Calibration sessions on the rig");
  auto args = std::make_shared<SessionCheckArgs>();
  auto* check = session->add_subcommand(
      "check", "Rig check: identify every instrument, generator lock, camera format, MCU stream");
  check->add_option("--rig", args->rig, "Rig configuration (generators:, hall_mcu:)")
      ->capture_default_str();
  check->add_option("--camera", args->camera,
                    "Camera: GigE Vision IP address, or V4L2 device (default: the rig file's)");
  check->add_option("--mcu", args->mcu, "Hall MCU serial device (default: the rig file's)");
  check->callback([args] {
    const gen::OpenGeneratorsGuard signals;  // from the start: docs/watchdog.md
    RunSessionCheck(*args);
  });

  auto run_args = std::make_shared<SessionRunArgs>();
  auto* run = session->add_subcommand(
      "run",
      "A guided calibration session on the real rig (journalled; `msmcal resume` continues it)");
  run->add_option("--rig", run_args->rig, "Rig file (docs/rig-file.md)")->capture_default_str();
  run->add_option("--camera", run_args->camera,
                  "Camera: GigE Vision IP address, or V4L2 device (default: the rig file's)");
  run->add_option("--mcu", run_args->mcu, "Hall MCU serial device (default: the rig file's)");
  run->add_option("--plan", run_args->plan,
                  "Plan folder: session.yaml + camera.yaml (`msmcal plan` writes one)")
      ->required();
  run->add_option("--out", run_args->out, "Session folder to create")->required();
  run->add_option("--rig-id", run_args->rig_id, "Rig identifier (catalogue)");
  run->add_option("--mirror-id", run_args->mirror_id, "Mirror identifier (catalogue)");
  run->add_option("--note", run_args->note, "Free text (catalogue)");
  run->add_option("--frame-rate", run_args->frame_rate_hz,
                  "Camera frame rate, Hz (default: the rig file's camera.frame_rate_hz; the rig "
                  "file's rule: (0, 1000], a period not shorter than camera.exposure_us)")
      ->each([run_args](const std::string&) { run_args->frame_rate_given = true; });
  run->add_option("--operator", run_args->operator_spec,
                  "Who changes the rig: console (guided terminal) or hook:CMD (CMD gets each "
                  "set-up's JSON on stdin, docs/lab-path.md)");
  run->add_option("--hook-timeout", run_args->hook_timeout_s,
                  "Seconds a hook may take per set-up (then: abort, safe state)");
  run->add_flag("--dry-run", run_args->dry_run,
                "Check the plan against the rig's limits and the free disk, print duration, "
                "prompts and disk needed; create nothing, contact no instrument");
  AddWebUiOptions(run, &run_args->web);
  run->callback([run_args] {
    const gen::OpenGeneratorsGuard signals;  // from the start: docs/watchdog.md
    RunSessionRun(*run_args);
  });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/6, AddSessionCommands);

}  // namespace msmcal::app
