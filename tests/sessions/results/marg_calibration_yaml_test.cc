#include "sessions/results/marg_calibration_yaml.h"

#include <gtest/gtest.h>

#include <string>
#include <utility>

#include "sessions/interchange/interchange_io.h"
#include "tests/testing/test_files.h"

namespace msmcal::results {
namespace {

using testing::Spit;
using testing::TempDir;

TEST(MargCalibrationYaml, RoundTripOfWhatApplyAndAttitudeUse) {
  TempDir dir;
  MargCalibrationFile file;
  marg::SensorCalibration mag;
  mag.offset = {12.5, -3.25, 0.1};
  mag.compensation << 1.01, 0.002, 0, 0.002, 0.99, 1e-4, 0, 1e-4, 1.0 / 3;
  mag.alignment = Eigen::Matrix3d::Identity();
  mag.alignment(0, 1) = -2e-3;
  file.calibration.magnetometer = mag;
  file.field_elevation_deg = -63.5;
  MargValidationFigures val;
  val.present = true;
  val.cost[0] = std::nan("");  // no accelerometer: no attitude costs
  val.mag_norm_relative_std = 0.004;
  const std::string text = FormatMargCalibrationYaml(file, val);
  EXPECT_EQ(text.rfind("format: msmcal-marg-calibration/1\n", 0), 0u) << text;
  EXPECT_EQ(text.find("mean_cost_raw"), std::string::npos) << text;
  Spit(dir.path() / "marg_calibration.yaml", text);
  const MargCalibrationFile back = ReadMargCalibrationYaml(dir.path() / "marg_calibration.yaml");
  ASSERT_TRUE(back.calibration.magnetometer.has_value());
  EXPECT_FALSE(back.calibration.accelerometer.has_value());
  EXPECT_EQ(back.calibration.magnetometer->offset, mag.offset);
  EXPECT_EQ(back.calibration.magnetometer->compensation, mag.compensation);
  EXPECT_EQ(back.calibration.magnetometer->alignment, mag.alignment);
  EXPECT_EQ(back.field_elevation_deg, file.field_elevation_deg);
}

TEST(MargCalibrationYaml, ABadNumberIsNamedWithItsLine) {
  TempDir dir;
  MargCalibrationFile file;
  file.calibration.magnetometer = marg::SensorCalibration{};
  std::string text = FormatMargCalibrationYaml(file, {});
  const size_t at = text.find("offset: [");
  text.replace(at, std::string("offset: [").size() + 1, "offset: [x");
  Spit(dir.path() / "bad.yaml", text);
  try {
    ReadMargCalibrationYaml(dir.path() / "bad.yaml");
    FAIL() << "no error";
  } catch (const interchange::InterchangeError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.yaml:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("sensors.magnetometer.offset[0]: expected a number"),
              std::string::npos)
        << e.what();
  }
}

// Fuzz findings (docs/fuzzing.md): a document or sensor that is not a mapping and a
// field_elevation_deg that is not a number name the file and the line (yaml-cpp's "operator[]
// call on a scalar" / "bad conversion" escaped without them).
TEST(MargCalibrationYaml, AWrongShapeNamesTheFileAndTheLine) {
  const std::pair<const char*, const char*> cases[] = {
      {"abc\n", "m.yaml:1: expected a mapping"},
      {"- 1\n", "m.yaml:1: expected a mapping"},
      {"format: msmcal-marg-calibration/1\nsensors: {magnetometer: 1}\n",
       "m.yaml:2: sensors.magnetometer: expected a mapping"},
      {"format: msmcal-marg-calibration/1\nfield_elevation_deg: [x]\nsensors: {}\n",
       "m.yaml:2: field_elevation_deg: expected a number"},
  };
  for (const auto& [text, expected] : cases) {
    try {
      ParseMargCalibrationYaml(text, "m.yaml");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const interchange::InterchangeError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos)
          << text << " -> " << e.what();
    }
  }
}

}  // namespace
}  // namespace msmcal::results
