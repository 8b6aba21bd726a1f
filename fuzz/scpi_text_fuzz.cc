// libFuzzer target: the driver's SCPI reply parsers (drivers/scpi/scpi_text.h).
//
// Input: byte 0 picks the parser, the rest is the reply. Checks: each parser returns or throws
// std::invalid_argument, nothing else; ParseNumber(FormatNumber(x)) == x for every number it
// accepts; a parsed block header lies inside the data and FormatDefiniteBlock's header reads
// back as itself; SplitResponses keeps every byte outside the units' trimmed ends and splits
// into (top-level ';' count + 1) units; an identity has no field with a comma.
#include <cmath>
#include <cstdint>
#include <string>

#include "drivers/scpi/scpi_text.h"
#include "fuzz/fuzz_util.h"

using namespace msmcal;
using fuzz::Check;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string text = fuzz::Text(data + 1, size - 1);
  switch (data[0] % 6) {
    case 0: {
      double v = 0;
      if (!fuzz::Returns([&] { v = scpi::ParseNumber(text); })) break;
      if (!std::isfinite(v)) break;  // FormatNumber refuses non-finite values by contract
      const std::string f = scpi::FormatNumber(v);
      double back = 0;
      fuzz::MustReturn([&] { back = scpi::ParseNumber(f); }, "ParseNumber(FormatNumber)");
      Check(back == v || (v == 0 && back == 0), "number round trip: " + f);
      break;
    }
    case 1: {
      std::optional<scpi::BlockHeader> h;
      if (!fuzz::Returns([&] { h = scpi::ParseBlockHeader(text); }) || !h) break;
      Check(h->header_size >= 3 && h->header_size <= 11 && h->header_size <= text.size(),
            "block header size");
      // The payload size as the header's digits say; a block of that payload formats the same
      // header when the digits have no leading zeros.
      if (text[2] != '0' && h->payload_size < 4096) {
        const std::string block = scpi::FormatDefiniteBlock(std::string(h->payload_size, 'x'));
        Check(block.compare(0, h->header_size, text, 0, h->header_size) == 0,
              "FormatDefiniteBlock header differs from the parsed one");
      }
      break;
    }
    case 2: {
      scpi::ErrorEntry e;
      if (!fuzz::Returns([&] { e = scpi::ParseErrorEntry(text); })) break;
      Check(e.message.size() <= text.size(), "error message longer than the reply");
      break;
    }
    case 3: {
      scpi::Identity id;
      if (!fuzz::Returns([&] { id = scpi::ParseIdentity(text); })) break;
      for (const std::string* f : {&id.manufacturer, &id.model, &id.serial, &id.firmware})
        Check(f->find(',') == std::string::npos, "identity field with a comma");
      break;
    }
    case 4: {
      bool b = false;
      fuzz::Returns([&] { b = scpi::ParseBool(text); });
      (void)b;
      break;
    }
    case 5: {
      const auto units = scpi::SplitResponses(text);
      size_t separators = 0, total = 0;
      bool quoted = false;
      for (char c : text) {
        if (c == '"') quoted = !quoted;
        if (c == ';' && !quoted) ++separators;
      }
      for (const auto& u : units) {
        total += u.size();
        Check(scpi::Trim(u) == u, "a response unit is not trimmed");
      }
      Check(units.size() == separators + 1, "unit count != top-level ';' + 1");
      Check(total + separators <= text.size(), "units hold more bytes than the reply");
      (void)scpi::IsPrintable(text);
      break;
    }
  }
  return 0;
}
