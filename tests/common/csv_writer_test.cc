#include "common/csv_writer.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>

#include "processing/dataset/hall_csv.h"

namespace msmcal::common {
namespace {

TEST(CsvWriterTest, RowsOfLosslessNumbersAndText) {
  std::string out;
  AppendCsvRow(&out, 0.1, -0.0, 1e-7, 1e6, 2.5);
  AppendCsvRow(&out, int64_t{1000000}, uint32_t{7}, -3, std::string_view("frame_01.png"));
  AppendCsvRow(&out, std::numeric_limits<double>::max());
  EXPECT_EQ(out,
            "0.1,-0,1e-07,1e+06,2.5\n"
            "1000000,7,-3,frame_01.png\n"
            "1.7976931348623157e+308\n");
}

// The Hall CSV format (processing/dataset/hall_csv.h): the recorder's integer MCU time stays an
// integer, a recording's decimal time keeps its fraction.
TEST(CsvWriterTest, HallRowsKeepTheirWritersTimeForm) {
  std::string out = std::string(dataset::kHallReadingsHeader) + "\n";
  dataset::AppendHallReadingRow(&out, int64_t{2000000}, 12.5, -3.0, 0.25);
  dataset::AppendHallReadingRow(&out, 8999999.609, 1.0, 2.0, 3.0);
  EXPECT_EQ(out,
            "mcu_time_us,bx_uT,by_uT,bz_uT\n"
            "2000000,12.5,-3,0.25\n"
            "8999999.609,1,2,3\n");
  std::string clock;
  dataset::AppendClockEdgeRow(&clock, int64_t{1000000});
  dataset::AppendClockEdgeRow(&clock, 1000000.0);
  EXPECT_EQ(clock, "1000000\n1e+06\n");
}

}  // namespace
}  // namespace msmcal::common
