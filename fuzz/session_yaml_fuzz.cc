// libFuzzer target: session.yaml of the interchange folder (ParseSessionYaml).
//
// Checks: the parser returns or throws std::runtime_error naming "session.yaml"; an accepted
// session passes CheckRecording; FormatSessionYaml of it parses again (without error) to a
// recording that formats to the same text (round trip).
#include <cstdint>
#include <string>

#include "fuzz/fuzz_util.h"
#include "sessions/interchange/interchange_io.h"

using namespace msmcal;
using fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  dataset::Recording rec;
  if (!fuzz::Returns(
          [&] { interchange::ParseSessionYaml(fuzz::Text(data, size), "session.yaml", &rec); },
          "session.yaml"))
    return 0;
  const std::string problem = interchange::CheckRecording(rec);
  Check(problem.empty(), "accepted session fails CheckRecording: " + problem);
  const std::string text = interchange::FormatSessionYaml(rec);
  dataset::Recording back;
  fuzz::MustReturn([&] { interchange::ParseSessionYaml(text, "written", &back); },
                   "ParseSessionYaml(FormatSessionYaml)");
  Check(interchange::FormatSessionYaml(back) == text, "session.yaml round trip differs");
  return 0;
}
