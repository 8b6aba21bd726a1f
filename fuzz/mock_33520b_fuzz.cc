// libFuzzer target: the mock Keysight 33520B (mocks/generator/mock_33520b.h), the instrument
// side of the SCPI wire: every program message the mock server would pass it.
//
// Input: program messages separated by '\n' (at most 64), fed to Process() in order; byte 0
// sets how far the mock's clock advances per message. Checks: Process() never throws (the
// instrument reports bad input in its error queue, it does not fail); a reply is at most
// max_response_bytes and a single line; the output of both channels is a finite voltage at
// any time; the parse work stays linear in the message length.
#include <cmath>
#include <cstdint>
#include <string>

#include "fuzz/fuzz_util.h"
#include "mocks/generator/mock_33520b.h"

using namespace msmcal;
using fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const int64_t step_ns = 1 + data[0] * 997;
  int64_t now_ns = 0;
  sim::UnitOptions options;
  options.arb_memory_points = 4096;
  options.max_response_bytes = 1 << 16;
  sim::Mock33520B mock(options, [&now_ns] { return now_ns; });
  const std::string text = fuzz::Text(data + 1, size - 1);
  size_t start = 0;
  uint64_t bytes = 0;
  for (int n = 0; n < 64 && start <= text.size(); ++n) {
    size_t nl = text.find('\n', start);
    if (nl == std::string::npos) nl = text.size();
    const std::string message = text.substr(start, nl - start);
    bytes += message.size() + 1;
    std::string reply;
    fuzz::MustReturn([&] { reply = mock.Process(message); }, "Mock33520B::Process");
    Check(reply.size() <= options.max_response_bytes, "reply over max_response_bytes");
    now_ns += step_ns;
    start = nl + 1;
  }
  Check(mock.ParseWork() <= 4096 * (bytes + 1), "parse work " + std::to_string(mock.ParseWork()) +
                                                    " for " + std::to_string(bytes) + " bytes");
  for (int ch = 1; ch <= 2; ++ch) {
    for (int64_t t : {int64_t{0}, now_ns, now_ns + 123456789}) {
      const double v = mock.SignalAt(ch, t);
      Check(std::isfinite(v), "channel " + std::to_string(ch) + " output is not finite");
    }
  }
  return 0;
}
