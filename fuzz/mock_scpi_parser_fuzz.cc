// libFuzzer target: the mock instrument's SCPI program-message parser (mocks/generator/
// scpi_parser.h).
//
// Input: byte 0 picks the function, byte 1 the chunk size, the rest is the text. Checks:
// - framing: MessageFramer fed in chunks (erasing consumed prefixes, Shift) ends messages
//   exactly where FindMessageEnd does (a differential check between the two framers);
// - SplitProgramMessage returns (a failure is reported in the result, with a SCPI error code)
//   and every unit resolves to a path and header nodes; a header is matched against the
//   mock's own patterns;
// - HeaderPattern built from fuzzed text either throws std::invalid_argument or matches
//   within a bounded number of node comparisons (no exponential backtracking);
// - the parameter parsers return or refuse (nullopt), never throw.
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz/fuzz_util.h"
#include "mocks/generator/scpi_parser.h"

using namespace msmcal;
using fuzz::Check;

namespace {

void Framing(const std::string& stream, size_t chunk) {
  std::vector<size_t> want;
  for (size_t start = 0;;) {
    const auto end = sim::FindMessageEnd(std::string_view(stream).substr(start));
    if (!end) break;
    Check(start + *end < stream.size() && stream[start + *end] == '\n',
          "FindMessageEnd: not at a '\\n'");
    want.push_back(start + *end);
    start += *end + 1;
  }
  std::string buffer;
  size_t erased = 0;  // bytes of `stream` erased from the front of `buffer`
  sim::MessageFramer framer;
  std::vector<size_t> got;
  for (size_t i = 0; i < stream.size(); i += chunk) {
    buffer += stream.substr(i, chunk);
    while (auto end = framer.Next(buffer)) {
      got.push_back(erased + *end);
      // Consume the message as the server does: erase it, shift the framer.
      buffer.erase(0, *end + 1);
      erased += *end + 1;
      framer.Reset(0);
    }
    Check(framer.scanned() <= buffer.size(), "framer scanned past the buffer");
  }
  Check(got == want, "MessageFramer and FindMessageEnd disagree");
}

const char* const kPatterns[] = {
    "[SOURce#:]FREQuency[:CW]", "[SOURce#:]VOLTage[:LEVel][:IMMediate][:AMPLitude]",
    "OUTPut#[:STATe]",          "[SOURce#:]FUNCtion[:SHAPe]",
    "SYSTem:ERRor[:NEXT]",      "[SOURce#:]DATA:ARBitrary#:DAC",
    "TRIGger#:SOURce",          "*IDN",
};

void Split(const std::string& message) {
  sim::SplitResult r;
  if (!fuzz::Returns([&] { r = sim::SplitProgramMessage(message); })) return;
  if (r.failure) Check(r.failure->code < 0, "parse failure without a negative SCPI code");
  std::vector<std::string> path;
  for (const auto& unit : r.units) {
    const std::vector<std::string> full = sim::ResolvePath(unit, path);
    const auto nodes = sim::SplitHeaderNodes(full);
    Check(nodes.size() == full.size(), "SplitHeaderNodes lost nodes");
    for (const char* p : kPatterns) {
      const sim::HeaderPattern pattern(p);
      uint64_t work = 0;
      if (auto m = pattern.Match(nodes, &work)) {
        Check(nodes.size() <= pattern.max_nodes(), "matched more nodes than the pattern has");
      }
      Check(work <= 64 * (nodes.size() + 1) * pattern.max_nodes() + 64, "match work unbounded");
    }
  }
}

void Pattern(const std::string& text) {
  const size_t nl = text.find('\n');
  const std::string pattern_text = text.substr(0, nl);
  std::vector<std::string> nodes;
  if (nl != std::string::npos) {
    std::string rest = text.substr(nl + 1);
    size_t start = 0;
    while (true) {
      const size_t colon = rest.find(':', start);
      nodes.push_back(rest.substr(start, colon - start));
      if (colon == std::string::npos) break;
      start = colon + 1;
    }
  }
  std::optional<sim::HeaderPattern> pattern;
  if (!fuzz::Returns([&] { pattern.emplace(pattern_text); })) return;
  const auto split = sim::SplitHeaderNodes(nodes);
  uint64_t work = 0;
  const auto m = pattern->Match(split, &work);
  const uint64_t n = split.size() + 1, p = pattern->max_nodes() + 1;
  Check(work <= 4 * n * p + 16, "HeaderPattern::Match work " + std::to_string(work) + " for " +
                                    std::to_string(n) + " nodes, " + std::to_string(p) +
                                    " pattern nodes (backtracking?)");
  if (m) Check(split.size() <= pattern->max_nodes(), "matched more nodes than the pattern has");
}

void Parameters(const std::string& text) {
  for (const char* unit : {"HZ", "V", "DEG", "OHM", "S", "SA/S", ""}) {
    (void)sim::ParseNumericWithUnit(text, unit);
  }
  (void)sim::ParseBoolean(text);
  (void)sim::MatchMnemonic("SQUare", text);
  (void)sim::MatchMnemonic(text, "SQU");
  const std::string upper = sim::Upper(text);
  Check(upper.size() == text.size(), "Upper changed the length");
  if (auto v = sim::ParseNumericWithUnit(text, "HZ"); v && std::isfinite(*v)) {
    (void)sim::FormatReplyNumber(*v);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  const std::string text = fuzz::Text(data + 2, size - 2);
  switch (data[0] % 4) {
    case 0:
      Framing(text, 1 + data[1] % 64);
      break;
    case 1:
      Split(text);
      break;
    case 2:
      Pattern(text);
      break;
    case 3:
      Parameters(text);
      break;
  }
  return 0;
}
