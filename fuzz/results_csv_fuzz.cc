// libFuzzer target: the results/ CSVs (mirror_planes.csv, beams.csv, validation.csv).
//
// Input: byte 0 picks the file kind, the rest is its text. Checks: returns or throws
// std::runtime_error naming the file; an accepted file written with its Format*Csv parses
// again to the same rows (round trip through the lossless writer).
#include "fuzz/csv_fuzz.h"
#include "sessions/results/results_files.h"

using namespace msmcal;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  switch (data[0] % 3) {
    case 0:
      fuzz::CsvRoundTrip(
          data + 1, size - 1, "results/mirror_planes.csv",
          [](const std::string& t, const std::string& n) {
            return results::ParseMirrorPlanesCsv(t, n);
          },
          [](const auto& v) { return results::FormatMirrorPlanesCsv(v); });
      break;
    case 1:
      fuzz::CsvRoundTrip(
          data + 1, size - 1, "results/beams.csv",
          [](const std::string& t, const std::string& n) { return results::ParseBeamsCsv(t, n); },
          [](const auto& v) { return results::FormatBeamsCsv(v); });
      break;
    case 2:
      fuzz::CsvRoundTrip(
          data + 1, size - 1, "results/validation.csv",
          [](const std::string& t, const std::string& n) {
            return results::ParseValidationCsv(t, n);
          },
          [](const auto& v) { return results::FormatValidationCsv(v); });
      break;
  }
  return 0;
}
