// `msmcal resume DIR [--camera-address ADDR] [--guided]`: continues a session that was interrupted
// (Ctrl-C, a crash, SIGKILL, power loss) from the last step its journal (DIR/session.db) records:
// frames already recorded are kept and not taken again, a Hall recording cut short is kept aside
// and taken again, then the steps after acquisition (solve, Hall calibration) that have no output
// yet are run.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/command_registry.h"
#include "app/session_flow.h"
#include "drivers/generator/safe_state.h"
#include "mocks/rig/sim_options.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/report/session_report.h"
#include "simulation/truth/truth_comparison.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;

struct ResumeArgs {
  std::string dir;
  std::string camera_address = "127.0.0.1";
  bool guided = false;
};

void RunResume(const ResumeArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  const fs::path dir = fs::absolute(args.dir);
  const orchestrator::SessionJournalState journal = orchestrator::ReadSessionJournal(dir);
  if (!journal.exists)
    throw std::runtime_error(dir.string() +
                             ": no session journal (session.db) here: nothing to resume");
  std::printf("msmcal resume: %s (%s session, %zu frames recorded)\n", dir.string().c_str(),
              journal.run_kind.c_str(), journal.frames_recorded);
  for (const auto& [name, state] : journal.steps)
    std::printf("  %-16s %s\n", name.c_str(), state.c_str());
  std::fflush(stdout);

  std::vector<std::string> notes;
  auto progress = [&](const std::string& line) {
    std::printf("[%6.1f s] %s\n", elapsed(), line.c_str());
    std::fflush(stdout);
    notes.push_back(line);
  };
  if (journal.complete) {
    std::printf("acquisition complete before the resume (session.yaml written)\n");
  } else if (journal.run_kind == "demo") {
    DemoAcquisitionOptions acq;
    acq.sim = sim::ParseSimOptions(journal.run_config_yaml,
                                   (dir / "session.db").string() + " [config_yaml]");
    acq.camera_address = args.camera_address;
    acq.resume = true;
    acq.progress = progress;
    if (args.guided) MakeGuided(acq);
    (void)RunDemoAcquisition(dir, acq);
  } else if (journal.run_kind == "lab") {
    LabAcquisitionOptions lab = LabOptionsFromJournal(dir, journal.run_config_yaml);
    lab.plan = orchestrator::LoadSessionPlan(dir);
    lab.rig_id = journal.rig_id;
    lab.mirror_id = journal.mirror_id;
    lab.note = journal.note;
    lab.resume = true;
    lab.progress = progress;
    (void)RunLabAcquisition(dir, lab);
  } else {
    throw std::runtime_error(dir.string() + ": a '" + journal.run_kind +
                             "' session's acquisition cannot be continued by `msmcal resume` "
                             "(re-run a replay with `msmcal replay`)");
  }
  const FinishResult finished = FinishSession(dir, FinishOptions{}, &notes);
  const report::SessionReport report = report::WriteSessionReport(
      dir, {/*session_process=*/true, notes}, simulation::SimTruthSource());
  std::printf("\n%s", report.text.c_str());
  std::printf("\nreport: %s   (resume took %.1f s)\n", (dir / "report.html").string().c_str(),
              elapsed());
  if (!finished.ok()) throw CLI::RuntimeError(1);
}

void AddResumeCommands(CLI::App& app) {
  auto args = std::make_shared<ResumeArgs>();
  auto* resume = app.add_subcommand(
      "resume", "Continue an interrupted session from the last step its journal recorded");
  resume->add_option("DIR", args->dir, "Session folder (holds session.db)")->required();
  resume->add_option("--camera-address", args->camera_address,
                     "Address the mock GigE Vision camera serves on (demo sessions)");
  resume->add_flag("--guided", args->guided,
                   "Demo sessions: prompt on this terminal for every set-up (a lab session "
                   "resumes with the operator its journal holds: the console or its hook)");
  resume->callback([args] {
    const gen::OpenGeneratorsGuard signals;  // from the start: docs/watchdog.md
    RunResume(*args);
  });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/6, AddResumeCommands);

}  // namespace msmcal::app
