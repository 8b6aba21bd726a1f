// libFuzzer target: the results/ CSVs: the interchange ones (mirror_planes.csv, beams.csv,
// validation.csv) and msmcal's native ones (validation_detail.csv, validation_dots.csv,
// residuals.csv, hall_poses.csv).
//
// Input: byte 0 picks the file kind (modulo 7; the seeds of the first three kinds keep their
// byte 0 of 0, 1, 2), the rest is its text. Checks: returns or throws std::runtime_error naming
// the file; an accepted file written with its Format*Csv parses again to the same rows (round
// trip through the lossless writer).
#include "fuzz/csv_fuzz.h"
#include "sessions/results/results_files.h"

using namespace msmcal;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const uint8_t* text = data + 1;
  const size_t n = size - 1;
  switch (data[0] % 7) {
    case 0:
      fuzz::CsvRoundTrip(text, n, "results/mirror_planes.csv", results::ParseMirrorPlanesCsv,
                         results::FormatMirrorPlanesCsv);
      break;
    case 1:
      fuzz::CsvRoundTrip(text, n, "results/beams.csv", results::ParseBeamsCsv,
                         results::FormatBeamsCsv);
      break;
    case 2:
      fuzz::CsvRoundTrip(text, n, "results/validation.csv", results::ParseValidationCsv,
                         results::FormatValidationCsv);
      break;
    case 3:
      fuzz::CsvRoundTrip(text, n, "results/validation_detail.csv",
                         results::ParseValidationDetailCsv, results::FormatValidationDetailCsv);
      break;
    case 4:
      fuzz::CsvRoundTrip(text, n, "results/validation_dots.csv", results::ParseValidationDotsCsv,
                         results::FormatValidationDotsCsv);
      break;
    case 5:
      fuzz::CsvRoundTrip(text, n, "results/residuals.csv", results::ParseResidualsCsv,
                         results::FormatResidualsCsv);
      break;
    case 6:
      fuzz::CsvRoundTrip(text, n, "results/hall_poses.csv", results::ParseHallPosesCsv,
                         results::FormatHallPosesCsv);
      break;
  }
  return 0;
}
