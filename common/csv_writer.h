#pragma once
// One CSV row writer for every CSV file msmcal writes (the interchange format's hall/ and marg/
// files, results/, the simulator's truth): cells separated by ',', the row ended by '\n', no
// quoting (no cell of these files holds a comma). Numbers are lossless: a double in the
// shortest text that reads back to the same value (common::ShortestDouble: "0.1", "1e-07"), an
// integer as an integer; text cells as given.
//
//   AppendCsvRow(&out, r.mcu_time_us, r.bx_uT, r.by_uT, r.bz_uT);  // "1000,12.5,-3,0.25\n"

#include <concepts>
#include <string>
#include <string_view>

namespace msmcal::common {

void AppendCsvCell(std::string* out, double value);
void AppendCsvCell(std::string* out, long long value);
void AppendCsvCell(std::string* out, unsigned long long value);
void AppendCsvCell(std::string* out, std::string_view text);

// Integers other than (unsigned) long long (int, int64_t, uint32_t) as integers.
template <std::integral Int>
requires(!std::same_as<Int, bool> && !std::same_as<Int, char>) void AppendCsvCell(std::string* out,
                                                                                  Int value) {
  if constexpr (std::is_signed_v<Int>) {
    AppendCsvCell(out, static_cast<long long>(value));
  } else {
    AppendCsvCell(out, static_cast<unsigned long long>(value));
  }
}

// One row: the cells, ',' between them, '\n' at the end.
template <typename First, typename... Rest>
void AppendCsvRow(std::string* out, const First& first, const Rest&... rest) {
  AppendCsvCell(out, first);
  ((*out += ',', AppendCsvCell(out, rest)), ...);
  *out += '\n';
}

}  // namespace msmcal::common
