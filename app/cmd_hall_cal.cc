// `msmcal hall calibrate DIR`, `msmcal hall predict MODEL IN.csv OUT.csv`: the Hall-sensor
// calibration of MSM paper Sec. V-B (processing/hall) on an interchange folder, and the live
// predictor on recorded readings.
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "app/command_registry.h"
#include "app/hall_cal_io.h"
#include "processing/hall/calibration.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;

void RunCalibrate(const std::string& dir, int repetitions, uint64_t seed, const std::string& model_name) {
  const auto t0 = std::chrono::steady_clock::now();
  const dataset::Recording rec = interchange::ReadRecording(dir);
  const fs::path planes_csv = fs::path(dir) / "results" / "mirror_planes.csv";
  if (!fs::exists(planes_csv))
    throw std::runtime_error(planes_csv.string() + ": not found; run `msmcal solve " + dir + "` first");
  const auto planes = interchange::ReadMirrorPlanesCsv(planes_csv);
  HallCalibrationSetup setup = MakeHallCalibrationSetup(rec, planes, dir);
  hall::HallCalibrationOptions options;
  options.repetitions = repetitions;
  options.seed = seed;
  if (!model_name.empty() && model_name != "best") {
    hall::HallModelKind kind;
    if (!hall::ParseHallModelKind(model_name, &kind))
      throw std::runtime_error("--model: expected linear|sine|quadratic|cubic|best, got '" + model_name + "'");
    options.models = {kind};
  }
  const hall::HallCalibrationResult result = hall::CalibrateHall(setup.Input(), options);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const fs::path out = fs::path(dir) / "results" / "hall_model.yaml";
  interchange::WriteFileAtomically(out, HallModelYaml(result, options));
  std::printf("%s", FormatTableTwo(result, options).c_str());
  std::printf("clock: actual %d edges (%d missing, %d rejected), rate error %.2f ppm, jitter %.2f us\n",
              result.actual_time_base.edges_used, result.actual_time_base.edges_missing,
              result.actual_time_base.edges_rejected, result.actual_time_base.RateErrorPpm(),
              result.actual_time_base.jitter_rms_us);
  std::printf("model: %s, delta_t = %.4f ms, wrote %s (%.1f s)\n", hall::ToString(result.final_fit.model.kind),
              result.final_fit.model.delta_t_s * 1e3, out.string().c_str(), seconds);
}

void RunPredict(const std::string& model_file, const std::string& in_csv, const std::string& out_csv,
                const std::string& clock_csv) {
  const LoadedHallModel loaded = ReadHallModelYaml(model_file);
  const auto readings = interchange::ReadHallReadingsCsv(in_csv);
  hall::TimeBase tb = loaded.time_base;
  fs::path clock = clock_csv;
  if (clock.empty()) {
    const fs::path in(in_csv);
    const fs::path sibling = in.parent_path() / (in.stem().string() + "_clock.csv");
    if (fs::exists(sibling)) clock = sibling;
  }
  if (!clock.empty()) {
    dataset::HallRecording rec = interchange::ReadHallCsv(in_csv, clock);
    tb = hall::FitTimeBase(rec.clock_edges_us, loaded.time_base.pattern_period_s);
    spdlog::info("time base from {}: rate error {:.2f} ppm", clock.string(), tb.RateErrorPpm());
  } else {
    spdlog::warn("no clock file for {}: using the calibration session's time base", in_csv);
  }
  const hall::HallPredictor predictor(loaded.model, loaded.background, loaded.actual_mean_uT);
  std::vector<double> t(readings.size());
  std::vector<Eigen::Vector3d> raw(readings.size()), pose(readings.size());
  for (size_t i = 0; i < readings.size(); ++i) {
    t[i] = tb.GeneratorTime(readings[i].mcu_time_us);
    raw[i] = Eigen::Vector3d(readings[i].bx_uT, readings[i].by_uT, readings[i].bz_uT);
  }
  const auto t0 = std::chrono::steady_clock::now();
  predictor.PredictBatch(t.data(), raw.data(), pose.data(), t.size());
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::ostringstream s;
  s << "mcu_time_us,t_s,alpha_deg,beta_deg,trans_mm\n";
  const double dt = loaded.model.delta_t_s;
  for (size_t i = 0; i < t.size(); ++i) {
    s << interchange::FormatDouble(readings[i].mcu_time_us) << ',' << interchange::FormatDouble(t[i] - dt) << ','
      << interchange::FormatDouble(pose[i].x()) << ',' << interchange::FormatDouble(pose[i].y()) << ','
      << interchange::FormatDouble(pose[i].z()) << '\n';
  }
  interchange::WriteFileAtomically(out_csv, s.str());
  std::printf("predicted %zu poses (%.1f M readings/s) into %s\n", t.size(),
              secs > 0 ? t.size() / secs / 1e6 : 0.0, out_csv.c_str());
}

void AddHallCalibrationCommands(CLI::App& app) {
  CLI::App* hall = GetOrAddSubcommand(app, "hall", "Hall sensor: recording, calibration, prediction");
  {
    auto* cmd = hall->add_subcommand("calibrate", "Fit the Hall models and dt on an interchange folder (needs results/mirror_planes.csv)");
    auto dir = std::make_shared<std::string>();
    auto reps = std::make_shared<int>(50);
    auto seed = std::make_shared<uint64_t>(1);
    auto model = std::make_shared<std::string>("best");
    cmd->add_option("DIR", *dir, "interchange folder")->required()->check(CLI::ExistingDirectory);
    cmd->add_option("--repetitions", *reps, "train/test splits for the model comparison (Table II)")->check(CLI::PositiveNumber);
    cmd->add_option("--seed", *seed, "seed of the random splits");
    cmd->add_option("--model", *model, "linear|sine|quadratic|cubic|best");
    cmd->callback([=] { RunCalibrate(*dir, *reps, *seed, *model); });
  }
  {
    auto* cmd = hall->add_subcommand("predict", "Map Hall readings to mirror poses with a calibrated model");
    auto model = std::make_shared<std::string>();
    auto in = std::make_shared<std::string>();
    auto out = std::make_shared<std::string>();
    auto clock = std::make_shared<std::string>();
    cmd->add_option("MODEL", *model, "results/hall_model.yaml")->required()->check(CLI::ExistingFile);
    cmd->add_option("IN", *in, "readings CSV (mcu_time_us,bx_uT,by_uT,bz_uT)")->required()->check(CLI::ExistingFile);
    cmd->add_option("OUT", *out, "poses CSV (mcu_time_us,t_s,alpha_deg,beta_deg,trans_mm)")->required();
    cmd->add_option("--clock", *clock, "clock-edge CSV of IN (default: IN's sibling <stem>_clock.csv)");
    cmd->callback([=] { RunPredict(*model, *in, *out, *clock); });
  }
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(60, AddHallCalibrationCommands);

}  // namespace msmcal::app
