// `msmcal experiment table2`: the MSM paper's Table II (Hall-sensor models) on the simulated rig.
// Poses come from a solved folder (`--from DIR` with results/mirror_planes.csv, i.e. the
// estimates of `msmcal solve`), or from the simulator's truth with Gaussian pose noise of the
// size the solver achieves (default), so that the Hall models are compared on paper-like data.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/command_registry.h"
#include "common/progress_line.h"
#include "common/units.h"
#include "mocks/rig/rig_simulator.h"
#include "mocks/rig/truth_io.h"
#include "processing/hall/calibration.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/results/finish_steps.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;

struct Table2Args {
  std::string config;
  std::string from;
  uint64_t seed = 1;
  int repetitions = 50;
  double pose_sigma_deg = 0.03;
  double pose_sigma_mm = 0.01;
  bool exact_field = false;
  // The paper's dataset: 130k actual and 65k background readings, 195 poses.
  double actual_s = 130;
  double background_s = 65;
  int triggers = 195;
  // Given on the command line: with --config, only these replace the file's values.
  bool seed_given = false, actual_given = false, background_given = false, triggers_given = false;
};

// Model error alone: every model fitted to noise-free poses with the simulator's exact
// foreground field (no readings, no interpolation).
void PrintExactFieldFits(const sim::RigSimulator& simulator,
                         const std::vector<dataset::MirrorPlaneRow>& planes) {
  const sim::HallModel& hm = simulator.hall();
  const double delay = simulator.options().hall.delta_t_s;
  const hall::FieldFunction fg = [&](double t) {
    return hm.MagnetFieldUT(simulator.motion().PoseAt(t - delay, sim::DriveMode::kScan));
  };
  std::vector<hall::PoseSample> poses;
  for (const auto& p : planes) {
    const auto pose = simulator.motion().PoseAt(p.t_s, sim::DriveMode::kScan);
    poses.push_back({p.t_s, Eigen::Vector3d(common::RadToDeg(pose.alpha_rad),
                                            common::RadToDeg(pose.beta_rad), pose.trans_mm)});
  }
  hall::HallFitOptions o;
  o.fast_frequency_hz = simulator.options().mirror.fast.frequency_hz;
  o.slow_frequency_hz = simulator.options().mirror.slow.frequency_hz;
  o.pattern_period_s = simulator.pattern_period_s();
  std::printf("model error with the exact field (no noise, no readings):\n");
  for (auto kind : {hall::HallModelKind::kLinear, hall::HallModelKind::kSine,
                    hall::HallModelKind::kQuadratic, hall::HallModelKind::kCubic}) {
    const auto r = hall::FitHallModel(kind, poses, fg, o);
    std::printf("  %-10s %.4f deg %.4f deg %.4f mm  dt %.4f ms\n", hall::ToString(kind),
                r.train_rms[0], r.train_rms[1], r.train_rms[2], r.model.delta_t_s * 1e3);
  }
}

void RunTable2(const Table2Args& args) {
  const auto t0 = std::chrono::steady_clock::now();
  results::HallCalibrationSetup setup;
  double true_delta_t = std::nan("");
  uint64_t seed = args.seed;  // the simulation's (the config file's without --seed) and the splits'
  if (!args.from.empty()) {
    const dataset::Recording rec = interchange::ReadRecording(args.from);
    const auto planes =
        results::ReadMirrorPlanesCsv(fs::path(args.from) / "results" / "mirror_planes.csv");
    setup = results::MakeHallCalibrationSetup(rec, planes, args.from);
    if (fs::exists(fs::path(args.from) / "truth"))
      true_delta_t = sim::ReadTruth(args.from).hall.delta_t_s;
    std::printf("poses: %zu estimated planes from %s\n", planes.size(), args.from.c_str());
  } else {
    // Without --config: the built-in options with the paper's dataset sizes (the options'
    // defaults); with it: the file's values, replaced only by the options given.
    const bool file = !args.config.empty();
    sim::SimOptions options = file ? sim::LoadSimOptions(args.config) : sim::SimOptions{};
    if (!file || args.seed_given) options.seed = args.seed;
    if (!file || args.actual_given) options.hall.actual_duration_s = args.actual_s;
    if (!file || args.background_given) options.hall.background_duration_s = args.background_s;
    if (!file || args.triggers_given) options.triggers.max_triggers = args.triggers;
    if (const std::string e = options.Validate(); !e.empty())
      throw std::runtime_error("experiment table2: " + e);
    seed = options.seed;
    const sim::RigSimulator simulator(options);
    const dataset::Recording rec = simulator.MakeRecording(/*with_hall=*/true);
    const sim::SimTruth truth = sim::MakeTruth(simulator, /*trajectory_rate_hz=*/1000.0);
    std::mt19937_64 rng(seed ^ 0x7ab1e2);
    std::normal_distribution<double> g(0, 1);
    std::vector<dataset::MirrorPlaneRow> planes = truth.mirror_planes;
    for (auto& p : planes) {
      p.alpha_deg += args.pose_sigma_deg * g(rng);
      p.beta_deg += args.pose_sigma_deg * g(rng);
      p.trans_mm += args.pose_sigma_mm * g(rng);
    }
    if (args.exact_field) {
      PrintExactFieldFits(simulator, truth.mirror_planes);
      // Reconstruction error of the recorded foreground against the exact one.
      const hall::TimeBase ta =
          hall::FitTimeBase(rec.hall_actual->clock_edges_us, simulator.pattern_period_s());
      const hall::TimeBase tb =
          hall::FitTimeBase(rec.hall_background->clock_edges_us, simulator.pattern_period_s());
      std::vector<double> t1, t2;
      std::vector<Eigen::Vector3d> b1, b2;
      hall::MapReadings(*rec.hall_actual, ta, &t1, &b1);
      hall::MapReadings(*rec.hall_background, tb, &t2, &b2);
      hall::Foreground fg{hall::PhaseProfile::Build(t1, b1, simulator.pattern_period_s()),
                          hall::PhaseProfile::Build(t2, b2, simulator.pattern_period_s())};
      const double delay = simulator.options().hall.delta_t_s;
      Eigen::Vector3d ss = Eigen::Vector3d::Zero(), amp = Eigen::Vector3d::Zero(),
                      mean = Eigen::Vector3d::Zero();
      const int n = 2000;
      std::vector<Eigen::Vector3d> exact(n);
      for (int i = 0; i < n; ++i) {
        const double t = simulator.pattern_period_s() * i / n;
        exact[i] = simulator.hall().MagnetFieldUT(
            simulator.motion().PoseAt(t - delay, sim::DriveMode::kScan));
        mean += exact[i] / n;
      }
      for (int i = 0; i < n; ++i) {
        const double t = simulator.pattern_period_s() * i / n;
        const Eigen::Vector3d e = fg.Value(t) - (exact[i] - mean);
        ss += e.cwiseAbs2() / n;
        amp = amp.cwiseMax((exact[i] - mean).cwiseAbs());
      }
      {
        std::vector<hall::PoseSample> poses;
        for (const auto& p : truth.mirror_planes)
          poses.push_back({p.t_s, Eigen::Vector3d(p.alpha_deg, p.beta_deg, p.trans_mm)});
        hall::HallFitOptions o;
        o.fast_frequency_hz = simulator.options().mirror.fast.frequency_hz;
        o.slow_frequency_hz = simulator.options().mirror.slow.frequency_hz;
        o.pattern_period_s = simulator.pattern_period_s();
        const auto r = hall::FitHallModel(
            hall::HallModelKind::kCubic, poses, [&](double t) { return fg.Value(t); }, o);
        std::printf("cubic on all readings (no split): %.4f deg %.4f deg %.4f mm dt %.4f ms\n",
                    r.train_rms[0], r.train_rms[1], r.train_rms[2], r.model.delta_t_s * 1e3);
      }
      std::printf(
          "foreground reconstruction: rms error %.3f %.3f %.3f uT, field amplitude %.1f %.1f %.1f "
          "uT; time base rate %.2f ppm\n",
          std::sqrt(ss[0]), std::sqrt(ss[1]), std::sqrt(ss[2]), amp[0], amp[1], amp[2],
          ta.RateErrorPpm());
    }
    setup = results::MakeHallCalibrationSetup(rec, planes, "simulation");
    true_delta_t = truth.hall.delta_t_s;
    std::printf("poses: %zu simulated planes (truth + N(0, %.3f deg), N(0, %.3f mm)), seed %llu\n",
                planes.size(), args.pose_sigma_deg, args.pose_sigma_mm,
                static_cast<unsigned long long>(seed));
  }
  double range[3] = {0, 0, 0};
  for (int k = 0; k < 3; ++k) {
    double lo = 1e300, hi = -1e300;
    for (const auto& p : setup.poses) {
      lo = std::min(lo, p.pose[k]);
      hi = std::max(hi, p.pose[k]);
    }
    range[k] = hi - lo;
  }
  std::printf(
      "ranges: alpha %.2f deg, beta %.2f deg, trans %.2f mm (paper: 4.37 deg, 17.17 deg, 1.04 "
      "mm)\n",
      range[0], range[1], range[2]);
  std::printf("readings: actual %zu, background %zu\n", setup.actual.readings.size(),
              setup.background.readings.size());
  hall::HallCalibrationOptions options;
  options.repetitions = args.repetitions;
  options.seed = seed;
  common::ProgressLine progress("experiment table2",
                                static_cast<size_t>(std::max(0, args.repetitions)),
                                "repetitions");  // on a terminal only (stderr)
  options.on_repetition = [&](int done, int) { progress.Update(static_cast<size_t>(done)); };
  const hall::HallCalibrationResult r = hall::CalibrateHall(setup.Input(), options);
  progress.Finish();
  std::printf("%s", results::FormatTableTwo(r, options).c_str());
  for (const auto& m : r.table) {
    if (!std::isnan(true_delta_t))
      std::printf("dt %-10s %.4f +- %.4f ms (truth %.4f ms, error %.1f us)\n",
                  hall::ToString(m.kind), m.delta_t_mean_s * 1e3, m.delta_t_std_s * 1e3,
                  true_delta_t * 1e3, (m.delta_t_mean_s - true_delta_t) * 1e6);
  }
  std::printf("time: %.1f s\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}

void AddTable2Command(CLI::App& app) {
  CLI::App* exp =
      GetOrAddSubcommand(app, "experiment", "Reproduce the papers' tables on simulated data");
  auto* cmd = exp->add_subcommand(
      "table2", "MSM paper Table II: Hall models (linear, sine, ours) with dt, 4:1 splits");
  auto args = std::make_shared<Table2Args>();
  auto* config = cmd->add_option("--config", args->config,
                                 "simulation config (default: built-in, as config/sim.yaml, with "
                                 "the paper's dataset sizes); its seed, Hall durations and "
                                 "max_triggers are kept unless given below")
                     ->check(CLI::ExistingFile);
  auto* from =
      cmd->add_option("--from", args->from, "use a solved interchange folder instead of simulating")
          ->check(CLI::ExistingDirectory);
  cmd->add_option("--seed", args->seed, "simulation and split seed (default 1, or --config's)")
      ->each([args](const std::string&) { args->seed_given = true; });
  cmd->add_option("--repetitions", args->repetitions, "random splits")->check(CLI::PositiveNumber);
  // What only a simulation uses is refused with --from (it would be ignored).
  std::vector<CLI::Option*> simulation_only{config};
  simulation_only.push_back(cmd->add_option("--pose-sigma-deg", args->pose_sigma_deg,
                                            "noise added to true angles when simulating"));
  simulation_only.push_back(cmd->add_option("--pose-sigma-mm", args->pose_sigma_mm,
                                            "noise added to true translations when simulating"));
  simulation_only.push_back(
      cmd->add_option("--actual-s", args->actual_s,
                      "seconds of the actual Hall recording (default 130: the paper's 130k "
                      "readings; or --config's)")
          ->each([args](const std::string&) { args->actual_given = true; }));
  simulation_only.push_back(
      cmd->add_option("--background-s", args->background_s,
                      "seconds of the background recording (default 65: the paper's 65k "
                      "readings; or --config's)")
          ->each([args](const std::string&) { args->background_given = true; }));
  simulation_only.push_back(
      cmd->add_option("--triggers", args->triggers,
                      "trigger poses wanted (default 195: the paper's; or --config's "
                      "max_triggers; the simulator keeps those whose dots stay apart)")
          ->each([args](const std::string&) { args->triggers_given = true; }));
  simulation_only.push_back(
      cmd->add_flag("--exact-field", args->exact_field,
                    "also fit every model to the simulator's exact field (model error alone)"));
  for (CLI::Option* o : simulation_only) from->excludes(o);
  cmd->callback([args] { RunTable2(*args); });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(91, AddTable2Command);

}  // namespace msmcal::app
