// `msmcal simulate OUT_DIR [--config F] [--seed N] [--no-images] [--jobs N] [--overwrite]`:
// runs the rig simulator (mocks/rig) and writes a complete interchange folder (session.yaml,
// camera.yaml, step1/ and step2/ images, hall/ recordings with clock files, optional marg/) plus
// the ground truth under truth/.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "app/command_registry.h"
#include "common/progress_line.h"
#include "mocks/marg/marg_simulator.h"
#include "mocks/rig/rig_simulator.h"
#include "mocks/rig/sim_options.h"
#include "mocks/rig/truth_io.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;

struct SimulateArgs {
  std::string out_dir;
  std::string config;
  std::optional<uint64_t> seed;  // none: the config's
  bool no_images = false;
  bool overwrite = false;
  int jobs = 0;
};

// The entries a simulated folder consists of (removed by --overwrite, nothing else).
const char* const kOwnedEntries[] = {"session.yaml", "camera.yaml", "step1", "step2",
                                     "hall",         "marg",        "truth"};

void PrepareOutDir(const SimulateArgs& args) {
  const fs::path out(args.out_dir);
  if (fs::exists(out)) {
    if (!fs::is_directory(out))
      throw std::runtime_error(args.out_dir + ": exists and is not a folder");
    if (!fs::is_empty(out)) {
      if (!args.overwrite) {
        throw std::runtime_error(args.out_dir +
                                 ": folder is not empty (use --overwrite to replace "
                                 "a simulated folder)");
      }
      // Only a simulated folder: it has the simulator's truth/ and no journal (a recorded
      // session has session.db; its images and Hall recordings are never removed here).
      if (!fs::is_directory(out / "truth") || fs::exists(out / "session.db"))
        throw std::runtime_error(args.out_dir +
                                 ": --overwrite replaces only a folder `msmcal simulate` wrote "
                                 "(it has truth/ and no session.db journal); this one is not: "
                                 "choose another OUT_DIR");
      for (const char* e : kOwnedEntries) fs::remove_all(out / e);
      // What was computed from the old data would describe the new one wrongly.
      for (const char* e : {"results", "report.html"}) fs::remove_all(out / e);
    }
  }
  fs::create_directories(out);
}

// Renders every frame on `jobs` threads (the renderer is thread-safe) and writes the PNGs.
void RenderAll(const sim::RigSimulator& sim, const fs::path& out, int jobs) {
  const size_t n1 = sim.step1_frames().size();
  const size_t total = n1 + sim.step2_frames().size();
  std::atomic<size_t> next{0};
  std::mutex error_mutex;
  std::exception_ptr error;
  common::ProgressLine progress("simulate", total, "frames rendered");  // on a terminal only
  auto worker = [&] {
    for (size_t i = next++; i < total; i = next++) {
      try {
        if (i < n1) {
          interchange::WriteImageAtomically(out / sim.step1_frames()[i].file,
                                            sim.RenderStep1Frame(i));
        } else {
          interchange::WriteImageAtomically(out / sim.step2_frames()[i - n1].file,
                                            sim.RenderStep2Frame(i - n1));
        }
        progress.Step();
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        next = total;
      }
    }
  };
  std::vector<std::thread> threads;
  for (int k = 1; k < jobs; ++k) threads.emplace_back(worker);
  worker();
  for (auto& t : threads) t.join();
  if (error) std::rethrow_exception(error);
}

void RunSimulate(const SimulateArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  sim::SimOptions options =
      args.config.empty() ? sim::SimOptions{} : sim::LoadSimOptions(args.config);
  if (args.seed) options.seed = *args.seed;
  if (const std::string err = options.Validate(); !err.empty()) throw std::runtime_error(err);

  const sim::RigSimulator sim(options);
  for (const auto& w : sim.warnings()) spdlog::warn("simulate: {}", w);
  PrepareOutDir(args);
  const fs::path out(args.out_dir);

  dataset::Recording rec = sim.MakeRecording(/*with_hall=*/true);
  if (options.marg) {
    const sim::MargSimulation marg = sim::SimulateMarg(sim::MargSimConfig{}, options.seed);
    rec.marg_plane_rotation = marg.plane_rotation;
    rec.marg_free_rotation = marg.free_rotation;
    rec.marg_validation = marg.validation;
    sim::WriteMargTruth(out, marg.truth);
  }

  const int jobs = args.jobs > 0 ? args.jobs : std::max(1u, std::thread::hardware_concurrency());
  if (!args.no_images) RenderAll(sim, out, jobs);
  sim::WriteTruth(out, sim::MakeTruth(sim));
  // session.yaml last: a folder with a session.yaml is complete.
  interchange::WriteRecording(out, rec);

  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf(
      "simulated %s (seed %llu): %zu step1 + %zu step2 frames%s, %zu triggers (T = %g s), %d beams "
      "(fan %.2f deg, spanning %.2f deg), hall %zu actual + %zu background readings, "
      "%zu + %zu clock edges%s, %.2f s\n",
      args.out_dir.c_str(), static_cast<unsigned long long>(options.seed), rec.step1.size(),
      rec.step2.size(), args.no_images ? " (no images)" : "", rec.triggers.size(),
      sim.pattern_period_s(), options.beams.count, sim.fan_angle_deg(),
      options.beams.spanning_angle_deg, rec.hall_actual->readings.size(),
      rec.hall_background->readings.size(), rec.hall_actual->clock_edges_us.size(),
      rec.hall_background->clock_edges_us.size(), options.marg ? ", marg/" : "", seconds);
}

void AddSimulateCommand(CLI::App& app) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Simulate the rig: write an interchange folder with ground truth under truth/");
  cmd->add_option("OUT_DIR", args->out_dir, "output folder (created; must be empty)")->required();
  cmd->add_option("--config", args->config,
                  "simulation config YAML (default: built-in = config/sim.yaml)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--seed", args->seed, "override the config's seed");
  cmd->add_flag("--no-images", args->no_images, "skip rendering the step1/step2 PNGs");
  cmd->add_flag("--overwrite", args->overwrite,
                "replace a previously simulated folder (removes only its own entries)");
  cmd->add_option("--jobs", args->jobs, "render threads (default: all cores)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([args] { RunSimulate(*args); });
}

MSMCAL_REGISTER_COMMANDS(/*order=*/20, AddSimulateCommand);

}  // namespace
}  // namespace msmcal::app
