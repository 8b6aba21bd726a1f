// libFuzzer target: results/hall_model.yaml as the predictor reads it (ParseHallModelYaml).
//
// Checks: returns or throws interchange::InterchangeError naming the file; an accepted model has 3
// rows of FeatureCount() parameters and a background profile with at least one bin.
#include <cstdint>
#include <string>

#include "fuzz/fuzz_util.h"
#include "sessions/results/results_files.h"

using namespace msmcal;
using fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  results::HallModelFile m;
  if (!fuzz::Returns(
          [&] { m = results::ParseHallModelYaml(fuzz::Text(data, size), "hall_model.yaml"); },
          "hall_model.yaml"))
    return 0;
  Check(m.model.a.rows() == 3 && m.model.a.cols() == m.model.FeatureCount(),
        "parameter matrix shape");
  Check(!m.background.bins().empty(), "empty background profile accepted");
  return 0;
}
