// `msmcal replay SESSION --out DIR [--compare] [--threads N] [--camera-address ADDR]` (issue 9):
// points the mock instruments at a recorded session — the generator pair configured as the
// original run was (from its journal), the GigE Vision camera serving the recorded image of each
// setup, the Hall MCU replaying hall/*.csv with MCU time preserved — and runs the same
// orchestrator into DIR (run kind "replay"), then the same post-acquisition steps (solve, Hall
// calibration and prediction) when the original has results/. With --compare, DIR is compared
// with SESSION (docs/replay.md): a table of what matched, and exit status 1 with the list of
// differences when anything differs.
// `msmcal replay SESSION --out DIR --compare-only`: the comparison alone, of two existing folders.
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
#include "sessions/orchestrator/orchestrator.h"
#include "sessions/replay/session_compare.h"
#include "simulation/replay/replay_rig.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;

struct ReplayArgs {
  std::string session;
  std::string out;
  bool compare = false;
  bool compare_only = false;
  int threads = 2;  // the solve's image threads, as `msmcal demo` (results do not depend on it)
  std::string camera_address = "127.0.0.1";
};

// Prints the comparison; true when identical.
bool PrintComparison(const fs::path& original, const fs::path& replayed) {
  const replay::SessionComparison c = replay::CompareSessions(original, replayed);
  std::printf("\ncomparison of %s (original) with %s (replay):\n%s", original.c_str(),
              replayed.c_str(), c.Table().c_str());
  if (!c.original_has_results)
    std::printf("the original has no results/ yet: acquisition compared only\n");
  const auto differences = c.Differences();
  if (differences.empty()) {
    std::printf("IDENTICAL: %zu files compared, every one the same\n", c.files.size());
    return true;
  }
  std::printf("DIFFERENT: %zu of %zu files differ:\n", differences.size(), c.files.size());
  for (const auto& d : differences)
    std::printf("  %-9s %s: %s%s%s\n", d.group.c_str(), d.file.c_str(), replay::ToString(d.verdict),
                d.detail.empty() ? "" : ": ", d.detail.c_str());
  return false;
}

void RunReplay(const ReplayArgs& args) {
  const fs::path source = fs::absolute(args.session).lexically_normal();
  const fs::path out = fs::absolute(args.out).lexically_normal();
  if (args.compare_only) {
    if (!PrintComparison(source, out)) throw CLI::RuntimeError(1);
    return;
  }
  if (args.threads < 1)
    throw std::runtime_error("--threads = " + std::to_string(args.threads) + ": must be >= 1");
  if (out == source) throw std::runtime_error("--out must differ from the replayed session");
  if (fs::exists(out) && !fs::is_empty(out))
    throw std::runtime_error(out.string() + ": exists and is not empty (choose another --out)");
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  const bool original_solved = fs::exists(source / "results" / "summary.json");

  {
    replay::ReplayRigOptions ro;
    ro.source = source;
    ro.camera_address = args.camera_address;
    replay::ReplayRig rig(ro);
    std::printf(
        "msmcal replay: %s (a %s session): %zu step-1 and %zu step-2 frames, %zu triggers; "
        "generators on ports %d and %d, camera %dx%d on %s, Hall MCU replaying on a pty\n",
        source.c_str(), rig.source_run().kind.c_str(), rig.Plan().step1.size(),
        rig.Plan().step2.size(), rig.Plan().triggers.size(), rig.generators_port(1),
        rig.generators_port(2), rig.Plan().camera.width, rig.Plan().camera.height,
        args.camera_address.c_str());
    std::fflush(stdout);
    const orchestrator::SessionResult session = orchestrator::RunSession(
        rig.MakeOrchestratorOptions(out), rig.Plan(), rig.world(), [&](const std::string& line) {
          std::printf("[%6.1f s] %s\n", elapsed(), line.c_str());
          std::fflush(stdout);
        });
    size_t rejected = 0;
    for (const auto& f : session.frames) rejected += f.accepted ? 0 : 1;
    std::printf(
        "[%6.1f s] replayed acquisition done: %zu frames (%zu rejected), Hall %llu + %llu "
        "readings\n",
        elapsed(), session.frames.size(), rejected,
        static_cast<unsigned long long>(session.background_readings),
        static_cast<unsigned long long>(session.actual_readings));
  }  // the mocks stop here

  if (original_solved) {
    FinishOptions fo;
    fo.skip_done = false;
    fo.threads = args.threads;
    const FinishResult finished = FinishSession(out, fo, nullptr);
    std::printf("[%6.1f s] solve %s, Hall calibration %s\n", elapsed(),
                finished.solved ? "ok" : "FAILED",
                finished.hall_calibrated && finished.hall_predicted ? "ok" : "not done");
  } else {
    std::printf("the original has no results/summary.json: not solving the replay\n");
  }
  if (args.compare) {
    if (!PrintComparison(source, out)) throw CLI::RuntimeError(1);
  }
  std::printf("replay: %s   (total %.1f s)\n", out.c_str(), elapsed());
}

void AddReplayCommands(CLI::App& app) {
  auto args = std::make_shared<ReplayArgs>();
  auto* cmd = app.add_subcommand(
      "replay",
      "Re-run a recorded session through the real drivers with the mocks fed by its recordings; "
      "--compare checks that the results are identical");
  cmd->add_option("SESSION", args->session, "Recorded session folder (with session.db)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", args->out, "Folder for the replayed session (must be absent or empty)")
      ->required();
  cmd->add_flag("--compare", args->compare,
                "Compare the replay with SESSION afterwards (exit 1 when anything differs)");
  cmd->add_flag("--compare-only", args->compare_only,
                "Do not replay: only compare the existing folder --out with SESSION");
  cmd->add_option("--threads", args->threads,
                  "The solve's image threads (the results do not depend on it; the MLE runs on "
                  "one Ceres thread)");
  cmd->add_option("--camera-address", args->camera_address,
                  "Address the mock GigE Vision camera serves on (port 3956)");
  cmd->callback([args] {
    const gen::OpenGeneratorsGuard signals;  // from the start: docs/watchdog.md
    RunReplay(*args);
  });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/7, AddReplayCommands);

}  // namespace msmcal::app
