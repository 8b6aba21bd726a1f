// `msmcal hall calibrate DIR`, `msmcal hall predict MODEL IN.csv OUT.csv`: the Hall-sensor
// calibration of MSM paper Sec. V-B (processing/hall) on an interchange folder, and the live
// predictor on recorded readings.
#include <algorithm>
#include <stdexcept>
#include <string>

#include "app/command_registry.h"
#include "app/step_output.h"
#include "common/progress_line.h"
#include "processing/hall/calibration.h"
#include "sessions/results/finish_steps.h"

namespace msmcal::app {
namespace {

void RunCalibrate(const std::string& dir, int repetitions, uint64_t seed,
                  const std::string& model_name) {
  hall::HallCalibrationOptions options;
  options.repetitions = repetitions;
  options.seed = seed;
  if (!model_name.empty() && model_name != "best") {
    hall::HallModelKind kind;
    if (!hall::ParseHallModelKind(model_name, &kind))
      throw std::runtime_error("--model: expected linear|sine|quadratic|cubic|best, got '" +
                               model_name + "'");
    options.models = {kind};
  }
  common::ProgressLine progress("hall calibrate", static_cast<size_t>(std::max(0, repetitions)),
                                "repetitions");  // on a terminal only
  // Leave-one-out (fewer poses than random splits need) runs one repetition per pose: the line
  // shows the share done.
  options.on_repetition = [&](int done, int total) {
    progress.Update(total > 0 ? static_cast<size_t>(done) * static_cast<size_t>(repetitions) /
                                    static_cast<size_t>(total)
                              : 0);
  };
  const results::HallCalibrationStepResult r = results::RunHallCalibration(dir, options);
  progress.Finish();
  PrintStepReport(r);
  if (!r.ok()) throw std::runtime_error(r.error);
}

void RunPredict(const std::string& model_file, const std::string& in_csv,
                const std::string& out_csv, const std::string& clock_csv) {
  const results::HallPredictionStepResult r =
      results::RunHallPrediction(model_file, in_csv, out_csv, clock_csv);
  PrintStepReport(r);
  if (!r.ok()) throw std::runtime_error(r.error);
}

void AddHallCalibrationCommands(CLI::App& app) {
  CLI::App* hall =
      GetOrAddSubcommand(app, "hall", "Hall sensor: recording, calibration, prediction");
  {
    auto* cmd = hall->add_subcommand(
        "calibrate",
        "Fit the Hall models and dt on an interchange folder (needs results/mirror_planes.csv)");
    auto dir = std::make_shared<std::string>();
    auto reps = std::make_shared<int>(50);
    auto seed = std::make_shared<uint64_t>(1);
    auto model = std::make_shared<std::string>("best");
    cmd->add_option("DIR", *dir, "interchange folder")->required()->check(CLI::ExistingDirectory);
    cmd->add_option("--repetitions", *reps, "train/test splits for the model comparison (Table II)")
        ->check(CLI::PositiveNumber);
    cmd->add_option("--seed", *seed, "seed of the random splits");
    cmd->add_option("--model", *model, "linear|sine|quadratic|cubic|best");
    cmd->callback([=] { RunCalibrate(*dir, *reps, *seed, *model); });
  }
  {
    auto* cmd = hall->add_subcommand("predict",
                                     "Map Hall readings to mirror poses with a calibrated model");
    auto model = std::make_shared<std::string>();
    auto in = std::make_shared<std::string>();
    auto out = std::make_shared<std::string>();
    auto clock = std::make_shared<std::string>();
    cmd->add_option("MODEL", *model, "results/hall_model.yaml")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("IN", *in, "readings CSV (mcu_time_us,bx_uT,by_uT,bz_uT)")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("OUT", *out, "poses CSV (mcu_time_us,t_s,alpha_deg,beta_deg,trans_mm)")
        ->required();
    cmd->add_option("--clock", *clock,
                    "clock-edge CSV of IN (default: IN's sibling <stem>_clock.csv)");
    cmd->callback([=] { RunPredict(*model, *in, *out, *clock); });
  }
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(60, AddHallCalibrationCommands);

}  // namespace msmcal::app
