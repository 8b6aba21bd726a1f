#include "acquisition/hall/hall_csv_writer.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "sessions/interchange/interchange_io.h"

namespace msmcal::acquisition {
namespace {

std::filesystem::path TempDir(const std::string& name) {
  auto dir = std::filesystem::path(::testing::TempDir()) /
             ("msmcal_hall_csv_" + name + "_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::string ReadText(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(HallCsvWriter, ClockPathSitsBesideTheReadings) {
  EXPECT_EQ(ClockCsvPathFor("/a/b/actual.csv"), std::filesystem::path("/a/b/actual_clock.csv"));
}

TEST(HallCsvWriter, WritesInterchangeColumnsLosslesslyAndIncrementally) {
  const auto dir = TempDir("roundtrip");
  const auto csv = dir / "actual.csv";
  HallCsvWriter writer(csv);
  hall_mcu::HallBatch batch;
  for (int i = 0; i < 100; ++i) {
    hall_mcu::HallSample s;
    s.mcu_time_us = 1000 * i + 3;
    s.bx_uT = 0.751 * (i - 50);
    s.by_uT = -0.1 * i / 3.0;
    s.bz_uT = 1e-7 * i;
    batch.readings.push_back(s);
  }
  batch.edges.push_back({0, 0, 500});
  batch.edges.push_back({0, 1, 50500});
  writer.Write(batch);
  // Already on disk before Close(): complete lines, readable by the interchange reader.
  const dataset::HallRecording mid = interchange::ReadHallCsv(csv, ClockCsvPathFor(csv));
  EXPECT_EQ(mid.readings.size(), 100u);
  writer.Close();
  EXPECT_EQ(ReadText(csv).substr(0, 30), "mcu_time_us,bx_uT,by_uT,bz_uT\n");
  EXPECT_EQ(ReadText(ClockCsvPathFor(csv)), "mcu_time_us\n500\n50500\n");
  const dataset::HallRecording back = interchange::ReadHallCsv(csv, ClockCsvPathFor(csv));
  ASSERT_EQ(back.readings.size(), 100u);
  for (size_t i = 0; i < 100; ++i) {
    EXPECT_EQ(back.readings[i].mcu_time_us, batch.readings[i].mcu_time_us);
    EXPECT_EQ(back.readings[i].bx_uT, batch.readings[i].bx_uT);  // bit-exact
    EXPECT_EQ(back.readings[i].by_uT, batch.readings[i].by_uT);
    EXPECT_EQ(back.readings[i].bz_uT, batch.readings[i].bz_uT);
  }
  EXPECT_EQ(back.clock_edges_us, (std::vector<double>{500, 50500}));
}

TEST(HallCsvWriter, ReadingsAfterAnMcuResetGoToTheirOwnFiles) {
  const auto dir = TempDir("reset");
  HallCsvWriter writer(dir / "background.csv");
  hall_mcu::HallBatch batch;
  batch.readings.push_back({});
  hall_mcu::HallSample after;
  after.epoch = 1;
  after.mcu_time_us = 7;
  batch.readings.push_back(after);
  writer.Write(batch);
  writer.Close();
  EXPECT_EQ(ReadText(dir / "background.csv"), "mcu_time_us,bx_uT,by_uT,bz_uT\n0,0,0,0\n");
  EXPECT_EQ(ReadText(dir / "background-reset1.csv"), "mcu_time_us,bx_uT,by_uT,bz_uT\n7,0,0,0\n");
  EXPECT_TRUE(std::filesystem::exists(dir / "background-reset1_clock.csv"));
}

TEST(HallCsvWriter, UnwritablePathThrowsNamingIt) {
  try {
    HallCsvWriter writer("/nonexistent_dir_msmcal/x.csv");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent_dir_msmcal/x.csv"), std::string::npos);
  }
}

}  // namespace
}  // namespace msmcal::acquisition
