// libFuzzer target: results/marg_calibration.yaml as `msmcal marg apply|attitude` read it
// (results::ParseMargCalibrationYaml).
//
// Checks: returns or throws std::runtime_error naming the file; an accepted calibration has a
// magnetometer or an accelerometer, and FormatMargCalibrationYaml of it parses again to a
// calibration that formats to the same text (round trip).
#include <cstdint>
#include <string>

#include "fuzz/fuzz_util.h"
#include "sessions/results/marg_calibration_yaml.h"

using namespace msmcal;
using fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  results::MargCalibrationFile c;
  if (!fuzz::Returns(
          [&] {
            c = results::ParseMargCalibrationYaml(fuzz::Text(data, size), "marg_calibration.yaml");
          },
          "marg_calibration.yaml"))
    return 0;
  Check(c.calibration.magnetometer || c.calibration.accelerometer, "no sensor accepted");
  const std::string text = results::FormatMargCalibrationYaml(c, results::MargValidationFigures{});
  results::MargCalibrationFile back;
  fuzz::MustReturn([&] { back = results::ParseMargCalibrationYaml(text, "written"); },
                   "ParseMargCalibrationYaml(FormatMargCalibrationYaml)");
  Check(results::FormatMargCalibrationYaml(back, results::MargValidationFigures{}) == text,
        "marg_calibration.yaml round trip differs");
  return 0;
}
