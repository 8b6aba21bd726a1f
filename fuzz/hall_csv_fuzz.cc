// libFuzzer target: hall/actual.csv (interchange::ParseHallReadingsCsv).
//
// Checks: returns or throws std::runtime_error naming the file; an accepted file written with
// FormatHallReadingsCsv parses again to the same rows (round trip through the lossless writer).
#include "fuzz/csv_fuzz.h"
#include "sessions/interchange/interchange_io.h"

using namespace msmcal;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  fuzz::CsvRoundTrip(
      data, size, "hall/actual.csv",
      [](const std::string& t, const std::string& n) {
        return interchange::ParseHallReadingsCsv(t, n);
      },
      [](const auto& v) { return interchange::FormatHallReadingsCsv(v); });
  return 0;
}
