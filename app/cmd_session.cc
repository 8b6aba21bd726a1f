// `msmcal session check --rig FILE --camera ADDR [--mcu DEVICE]`: the orchestrator's rig check
// against the instruments of a rig configuration (config/rig.yaml: `generators:` and `hall_mcu:`
// sections): identifies both generators and checks the reference lock and the signal limits,
// opens the camera (GigE Vision by address, or V4L2 by device; Mono8), identifies the Hall MCU and
// reads a status frame. Prints what it found and, when something is wrong, the list of problems
// (exit status 1). Generator outputs are left off.
//
// `msmcal session run --rig FILE --camera ADDR --plan DIR --out DIR [--mcu DEVICE] [--rig-id ID]
// [--mirror-id ID] [--note TEXT]`: a calibration session on the real rig, guided on this
// terminal (what to mount, move, remove before every frame and Hall recording; live quality
// figures; annotated previews in DIR/previews), journalled in DIR/session.db, then solved and
// the Hall sensor calibrated. The plan folder holds session.yaml and camera.yaml as the
// interchange format defines them (boards, beams, drive, clock, the trigger table and the frames
// to take). Interrupted, it continues with `msmcal resume DIR`. `--ui web[:PORT]`: the operator
// answers on the live view's page in a browser instead (app/web_ui.h).
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
#include "drivers/generator/rig_config.h"
#include "drivers/hall_mcu/hall_mcu_config.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/orchestrator/report.h"
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
  options.camera = args.camera;
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
  std::string camera;
  std::string mcu;
  std::string plan;
  std::string out;
  std::string rig_id, mirror_id, note;
  double frame_rate_hz = 10.0;
  WebUiArgs web;  // --ui web[:PORT], --ui-bind
};

void RunSessionRun(const SessionRunArgs& args) {
  namespace fs = std::filesystem;
  const auto start = std::chrono::steady_clock::now();
  std::unique_ptr<WebUi> web;  // --ui checked before any file is read
  if (args.web.enabled()) web = std::make_unique<WebUi>(args.web);
  const fs::path out = fs::absolute(args.out);
  if (fs::exists(out) && !fs::is_empty(out))
    throw std::runtime_error(out.string() +
                             ": exists and is not empty (an interrupted session continues with "
                             "`msmcal resume " +
                             out.string() + "`)");
  LabAcquisitionOptions lab;
  {
    std::ifstream in(args.rig, std::ios::binary);
    if (!in) throw std::runtime_error(args.rig + ": cannot read the rig configuration");
    std::stringstream text;
    text << in.rdbuf();
    lab.rig_yaml = text.str();
  }
  lab.rig_origin = args.rig;
  lab.camera_address = args.camera;
  lab.mcu_device = args.mcu;
  lab.camera_frame_rate_hz = args.frame_rate_hz;
  lab.plan = ReadPlanFolder(args.plan);
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
  const orchestrator::SessionReport report =
      orchestrator::BuildSessionReport(out, notes, simulation::SimTruthSource());
  interchange::WriteFileAtomically(out / "report.html", report.html);
  std::printf("\n%s\nreport: %s\n", report.text.c_str(), (out / "report.html").string().c_str());
  if (!finished.ok()) throw CLI::RuntimeError(1);
}

void AddSessionCommands(CLI::App& app) {
  CLI::App* session = GetOrAddSubcommand(app, "session", "Calibration sessions on the rig");
  auto args = std::make_shared<SessionCheckArgs>();
  auto* check = session->add_subcommand(
      "check", "Rig check: identify every instrument, generator lock, camera format, MCU stream");
  check->add_option("--rig", args->rig, "Rig configuration (generators:, hall_mcu:)");
  check
      ->add_option("--camera", args->camera,
                   "Camera: GigE Vision IP address, or V4L2 device (/dev/video0)")
      ->required();
  check->add_option("--mcu", args->mcu, "Hall MCU serial device (default: the rig file's)");
  check->callback([args] { RunSessionCheck(*args); });

  auto run_args = std::make_shared<SessionRunArgs>();
  auto* run = session->add_subcommand(
      "run",
      "A guided calibration session on the real rig (journalled; `msmcal resume` continues it)");
  run->add_option("--rig", run_args->rig, "Rig configuration (generators:, hall_mcu:)");
  run->add_option("--camera", run_args->camera,
                  "Camera: GigE Vision IP address, or V4L2 device (/dev/video0)")
      ->required();
  run->add_option("--mcu", run_args->mcu, "Hall MCU serial device (default: the rig file's)");
  run->add_option("--plan", run_args->plan,
                  "Plan folder: session.yaml + camera.yaml (frames to take, trigger table)")
      ->required();
  run->add_option("--out", run_args->out, "Session folder to create")->required();
  run->add_option("--rig-id", run_args->rig_id, "Rig identifier (catalogue)");
  run->add_option("--mirror-id", run_args->mirror_id, "Mirror identifier (catalogue)");
  run->add_option("--note", run_args->note, "Free text (catalogue)");
  run->add_option("--frame-rate", run_args->frame_rate_hz, "Camera frame rate, Hz");
  AddWebUiOptions(run, &run_args->web);
  run->callback([run_args] { RunSessionRun(*run_args); });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/6, AddSessionCommands);

}  // namespace msmcal::app
