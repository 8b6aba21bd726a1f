#pragma once
// I/O around the Hall calibration: interchange folder -> calibration input, and
// results/hall_model.yaml (interchange-format.md: model kind, parameters, delta_t_s, train/test
// RMS per output) written and read back for the predictor.

#include <string>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/hall/calibration.h"

namespace msmcal::app {

struct HallCalibrationSetup {
  dataset::HallRecording actual;
  dataset::HallRecording background;
  double pattern_period_s = 0;
  double fast_frequency_hz = 0;
  double slow_frequency_hz = 0;
  std::vector<hall::PoseSample> poses;
  // The calibration input; it points into this object.
  hall::HallCalibrationInput Input() const;
};

// Checks that the folder has both Hall recordings and poses; names what is missing.
HallCalibrationSetup MakeHallCalibrationSetup(const dataset::Recording& rec,
                                              const std::vector<dataset::MirrorPlaneRow>& planes,
                                              const std::string& dir_for_messages);

std::string HallModelYaml(const hall::HallCalibrationResult& result, const hall::HallCalibrationOptions& options);
// Table II as text.
std::string FormatTableTwo(const hall::HallCalibrationResult& result, const hall::HallCalibrationOptions& options);

struct LoadedHallModel {
  hall::HallModel model;
  hall::TimeBase time_base;
  hall::PhaseProfile background;
  Eigen::Vector3d actual_mean_uT = Eigen::Vector3d::Zero();
};
// Throws std::runtime_error naming the file and the field.
LoadedHallModel ReadHallModelYaml(const std::string& file);

}  // namespace msmcal::app
