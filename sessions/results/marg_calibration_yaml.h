#pragma once
// results/marg_calibration.yaml (format msmcal-marg-calibration/1), written by `msmcal marg
// calibrate` and read by `msmcal marg apply` / `attitude`. Per sensor:
//   calibrated = alignment * compensation * (raw - offset)
// with offset [3], compensation [3x3], alignment [3x3] (rows), plus figures; the validation
// recording's figures when there was one.

#include <filesystem>
#include <optional>
#include <string>

#include "processing/marg/marg_calibration.h"

namespace msmcal::results {

struct MargCalibrationFile {
  marg::MargCalibration calibration;
  std::optional<double> field_elevation_deg;
};

struct MargValidationFigures {
  bool present = false;
  double cost[3] = {0, 0, 0};  // mean attitude cost: raw, compensated, aligned-compensated
  double mag_norm_relative_std = 0;
};

// The file's text (numbers in the shortest round-trip form).
std::string FormatMargCalibrationYaml(const MargCalibrationFile& file,
                                      const MargValidationFigures& validation);
// Reads the calibration back (offset, compensation, alignment per sensor; the field elevation).
// Throws interchange::InterchangeError "file:line: sensors.magnetometer.offset: expected a
// sequence of 3 numbers".
MargCalibrationFile ReadMargCalibrationYaml(const std::filesystem::path& file);
// The same on the file's text (`file` names it in messages).
MargCalibrationFile ParseMargCalibrationYaml(const std::string& text,
                                             const std::filesystem::path& file);

}  // namespace msmcal::results
