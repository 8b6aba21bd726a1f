#pragma once
// The Hall CSV files of a recording (interchange-format.md, "Hall CSV files"), defined once for
// their writers (the recorder streaming from the MCU, acquisition/hall; the interchange writer,
// sessions/interchange) and their reader:
//   readings: header `mcu_time_us,bx_uT,by_uT,bz_uT`, one reading a row;
//   clock:    header `mcu_time_us`, one rising clock edge a row.
// Numbers through the one CSV writer (common/csv_writer.h): lossless. The MCU time is written as
// its writer holds it: the recorder's integer MCU timestamp as an integer ("1000000"), a
// recording's decimal time (which may carry a fraction) in the shortest round-trip form.

#include <string>

#include "common/csv_writer.h"

namespace msmcal::dataset {

inline constexpr const char* kHallReadingsHeader = "mcu_time_us,bx_uT,by_uT,bz_uT";
inline constexpr const char* kHallClockHeader = "mcu_time_us";

template <typename Time>
void AppendHallReadingRow(std::string* out, Time mcu_time_us, double bx_uT, double by_uT,
                          double bz_uT) {
  common::AppendCsvRow(out, mcu_time_us, bx_uT, by_uT, bz_uT);
}

template <typename Time>
void AppendClockEdgeRow(std::string* out, Time mcu_time_us) {
  common::AppendCsvRow(out, mcu_time_us);
}

}  // namespace msmcal::dataset
