// libFuzzer target: the simulator options, config/sim.yaml (ParseSimOptions).
//
// Checks: returns or throws std::runtime_error naming the file; accepted options are valid
// (Validate() empty, since the parser validates) and SimOptionsToYaml of them parses again to
// options that write the same text (round trip).
#include <cstdint>
#include <string>

#include "fuzz/fuzz_util.h"
#include "mocks/rig/sim_options.h"

using namespace msmcal;
using fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sim::SimOptions options;
  if (!fuzz::Returns([&] { options = sim::ParseSimOptions(fuzz::Text(data, size), "sim.yaml"); },
                     "sim.yaml"))
    return 0;
  Check(options.Validate().empty(), "accepted options fail Validate: " + options.Validate());
  const std::string text = sim::SimOptionsToYaml(options);
  sim::SimOptions back;
  fuzz::MustReturn([&] { back = sim::ParseSimOptions(text, "written"); },
                   "ParseSimOptions(SimOptionsToYaml)");
  Check(sim::SimOptionsToYaml(back) == text, "sim.yaml round trip differs");
  return 0;
}
