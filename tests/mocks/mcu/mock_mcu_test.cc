// The mock MCU on a real pty, talked to by the real driver (Boost.Asio serial_port opening the
// pty's path as it would open /dev/ttyACM0). No sleeps: the tests synchronise on the protocol
// (end-of-data status) and on the driver's stall deadline.
#include "mocks/mcu/mock_mcu.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <random>
#include <set>

#include "drivers/hall_mcu/hall_sensor.h"

namespace msmcal::sim {
namespace {

using hall_mcu::HallBatch;
using hall_mcu::ReadStatus;

std::unique_ptr<McuDataSource> Synthetic(double seconds, SyntheticMode mode = SyntheticMode::kScan,
                                         uint64_t seed = 1) {
  SyntheticSourceOptions o;
  o.mode = mode;
  o.duration_s = seconds;
  o.seed = seed;
  return std::make_unique<SyntheticSource>(o);
}

struct Received {
  std::vector<hall_mcu::HallSample> readings;
  std::vector<hall_mcu::ClockEdge> edges;
  std::vector<hall_mcu::MargReading> marg;
  ReadStatus last = ReadStatus::kOk;
  bool end_of_data = false;
};

// Reads until end of data, a stall or a close.
Received ReadAll(hall_mcu::HallSensor& sensor) {
  Received r;
  HallBatch batch;
  while (true) {
    batch.clear();
    const hall_mcu::ReadResult res = sensor.Read(&batch);
    r.readings.insert(r.readings.end(), batch.readings.begin(), batch.readings.end());
    r.edges.insert(r.edges.end(), batch.edges.begin(), batch.edges.end());
    r.marg.insert(r.marg.end(), batch.marg.begin(), batch.marg.end());
    r.last = res.status;
    if (batch.end_of_data) {
      r.end_of_data = true;
      return r;
    }
    if (res.status != ReadStatus::kOk) return r;
  }
}

hall_mcu::HallMcuOptions DriverOptions(const std::string& device, int stall_ms = 2000,
                                       int command_ms = 2000) {
  hall_mcu::HallMcuOptions o;
  o.device = device;
  o.stall_timeout_ms = stall_ms;
  o.command_timeout_ms = command_ms;
  return o;
}

void ExpectSameReading(const hall_mcu::HallSample& got, const hall_mcu::HallSample& sent) {
  EXPECT_EQ(got.seq, sent.seq);
  EXPECT_EQ(got.epoch, sent.epoch);
  EXPECT_EQ(got.mcu_time_us, sent.mcu_time_us);
  EXPECT_EQ(got.bx_uT, sent.bx_uT);  // exact: same registers, same table
  EXPECT_EQ(got.by_uT, sent.by_uT);
  EXPECT_EQ(got.bz_uT, sent.bz_uT);
}

TEST(MockMcu, IdentifyAndSettingsAreAcknowledged) {
  MockMcu mock({}, Synthetic(1));
  mock.Start();
  auto sensor = hall_mcu::OpenHallMcu(DriverOptions(mock.device_path()));
  hall_mcu::DeviceInfo info;
  ASSERT_TRUE(sensor->Identify(&info).ok);
  EXPECT_EQ(info.identify.board, "msmcal mock MCU");
  EXPECT_EQ(info.identify.sensor_type, hall_mcu::SensorType::kMlx90393);
  EXPECT_TRUE(sensor->SetRate(1000).ok);
  const hall_mcu::CommandResult bad = sensor->SetRate(0);
  EXPECT_FALSE(bad.ok);
  EXPECT_NE(bad.message.find("bad_value"), std::string::npos) << bad.message;
  hall_mcu::SensorSettings s;
  s.gain_sel = 3;
  s.res_x = 1;
  s.res_z = 2;
  EXPECT_TRUE(sensor->SetSensor(s).ok);
  EXPECT_TRUE(sensor->RequestStatus().ok);
  EXPECT_EQ(sensor->counters().status_frames, 2u);  // boot + requested
  ASSERT_TRUE(sensor->StartStreaming().ok);
  Received r = ReadAll(*sensor);
  ASSERT_TRUE(r.end_of_data);
  ASSERT_EQ(r.readings.size(), 1000u);
  EXPECT_EQ(r.readings[0].gain_sel, 3);
  EXPECT_EQ(r.readings[0].res_x, 1);
  EXPECT_EQ(r.readings[0].res_z, 2);
  EXPECT_EQ(mock.Log().commands, 6u);
}

// The acceptance test: 60 s of simulated 1 kHz data through a real pty, faster than real
// time; every reading the mock sent arrives, in order, with the same values.
TEST(MockMcu, SixtySecondsAtOneKilohertzArriveCompleteAndInOrder) {
  MockMcuOptions options;
  options.link_path = ::testing::TempDir() + "/msmcal_mock_ttyACM" + std::to_string(getpid());
  MockMcu mock(options, Synthetic(60));
  ASSERT_TRUE(std::filesystem::is_symlink(options.link_path));
  mock.Start();
  auto sensor = hall_mcu::OpenHallMcu(DriverOptions(options.link_path));
  ASSERT_TRUE(sensor->StartStreaming().ok);
  Received r = ReadAll(*sensor);
  ASSERT_TRUE(r.end_of_data);
  const MockMcuLog log = mock.Log();
  ASSERT_EQ(log.sent_readings.size(), 60000u);
  ASSERT_EQ(r.readings.size(), log.sent_readings.size());
  for (size_t i = 0; i < r.readings.size(); ++i) {
    ExpectSameReading(r.readings[i], log.sent_readings[i]);
    if (::testing::Test::HasFailure()) FAIL() << "at reading " << i;
  }
  ASSERT_EQ(r.edges.size(), 120u);  // one every 0.5 s
  ASSERT_EQ(r.edges.size(), log.sent_edges.size());
  for (size_t i = 0; i < r.edges.size(); ++i) {
    EXPECT_EQ(r.edges[i].mcu_time_us, log.sent_edges[i].mcu_time_us);
  }
  const hall_mcu::HallCounters& c = sensor->counters();
  EXPECT_EQ(c.readings, 60000u);
  EXPECT_EQ(c.readings_lost, 0u);
  EXPECT_EQ(c.clock_edges_lost, 0u);
  EXPECT_EQ(c.crc_errors, 0u);
  EXPECT_EQ(c.bytes_discarded, 0u);
  EXPECT_EQ(c.resets, 0u);
  EXPECT_GE(c.status_frames, 600u);  // heartbeats every 100 ms of MCU time
}

TEST(MockMcu, EveryInjectedLossIsCountedExactly) {
  MockMcuOptions options;
  options.seed = 99;
  // Data frames are readings and edges interleaved; the indices below hit both kinds.
  for (uint64_t i = 37; i < 20000; i += 397) options.faults.push_back({McuFaultKind::kFlipBit, i});
  for (uint64_t i = 101; i < 20000; i += 613) options.faults.push_back({McuFaultKind::kDropByte, i});
  options.faults.push_back({McuFaultKind::kFlipBit, 19998});   // last frames: only the final status
  options.faults.push_back({McuFaultKind::kDropByte, 19999});  // reveals these losses
  MockMcu mock(options, Synthetic(19.99));
  mock.Start();
  auto sensor = hall_mcu::OpenHallMcu(DriverOptions(mock.device_path()));
  ASSERT_TRUE(sensor->StartStreaming().ok);
  Received r = ReadAll(*sensor);
  ASSERT_TRUE(r.end_of_data);
  const MockMcuLog log = mock.Log();
  EXPECT_GT(log.damaged_reading_seqs.size(), 50u);
  EXPECT_EQ(log.flipped_bits + log.dropped_bytes, options.faults.size());
  const hall_mcu::HallCounters& c = sensor->counters();
  EXPECT_EQ(c.readings_lost, log.damaged_reading_seqs.size());
  EXPECT_EQ(c.clock_edges_lost, log.damaged_edge_seqs.size());
  EXPECT_EQ(c.readings + c.readings_lost, log.readings_sent_total);
  ASSERT_EQ(r.readings.size(), log.sent_readings.size());
  for (size_t i = 0; i < r.readings.size(); ++i)
    ExpectSameReading(r.readings[i], log.sent_readings[i]);
  EXPECT_GT(c.bytes_discarded, 0u);
}

TEST(MockMcu, RandomAndConsecutiveDamageIsCountedExactly) {
  MockMcuOptions options;
  options.seed = 2024;
  std::mt19937_64 rng(17);
  std::set<uint64_t> frames;
  while (frames.size() < 400) frames.insert(rng() % 15000);
  for (uint64_t f = 7000; f < 7010; ++f) frames.insert(f);  // a burst of damaged frames
  for (uint64_t f : frames) {
    options.faults.push_back({rng() % 2 ? McuFaultKind::kFlipBit : McuFaultKind::kDropByte, f});
  }
  MockMcu mock(options, Synthetic(15));
  mock.Start();
  auto sensor = hall_mcu::OpenHallMcu(DriverOptions(mock.device_path()));
  ASSERT_TRUE(sensor->StartStreaming().ok);
  Received r = ReadAll(*sensor);
  ASSERT_TRUE(r.end_of_data);
  const MockMcuLog log = mock.Log();
  ASSERT_EQ(log.flipped_bits + log.dropped_bytes, frames.size());
  const hall_mcu::HallCounters& c = sensor->counters();
  EXPECT_EQ(c.readings_lost, log.damaged_reading_seqs.size());
  EXPECT_EQ(c.clock_edges_lost, log.damaged_edge_seqs.size());
  ASSERT_EQ(r.readings.size(), log.sent_readings.size());
  for (size_t i = 0; i < r.readings.size(); ++i) {
    ExpectSameReading(r.readings[i], log.sent_readings[i]);
  }
  ASSERT_EQ(r.edges.size(), log.sent_edges.size());
}

TEST(MockMcu, ResetMidStreamIsDetectedAndStreamingResumes) {
  MockMcuOptions options;
  options.faults.push_back({McuFaultKind::kReset, 2500});
  options.faults.push_back({McuFaultKind::kFlipBit, 4000});
  MockMcu mock(options, Synthetic(6));
  mock.Start();
  auto sensor = hall_mcu::OpenHallMcu(DriverOptions(mock.device_path()));
  ASSERT_TRUE(sensor->StartStreaming().ok);
  Received r;
  HallBatch batch;
  uint64_t resets_handled = 0;
  while (!r.end_of_data) {
    batch.clear();
    ASSERT_EQ(sensor->Read(&batch).status, ReadStatus::kOk);
    r.readings.insert(r.readings.end(), batch.readings.begin(), batch.readings.end());
    r.end_of_data = batch.end_of_data;
    if (sensor->counters().resets > resets_handled) {  // the MCU boots idle: restart it
      resets_handled = sensor->counters().resets;
      ASSERT_TRUE(sensor->StartStreaming().ok);
    }
  }
  const MockMcuLog log = mock.Log();
  const hall_mcu::HallCounters& c = sensor->counters();
  EXPECT_EQ(log.resets, 1u);
  EXPECT_EQ(c.resets, 1u);
  EXPECT_EQ(c.readings_lost, log.damaged_reading_seqs.size());
  EXPECT_EQ(c.clock_edges_lost, log.damaged_edge_seqs.size());
  // The frame cut by the reset is not a sequence gap (the sequence restarts); the decoder saw it
  // as a damaged frame.
  EXPECT_GE(c.crc_errors + c.bad_headers, 1u);
  ASSERT_EQ(r.readings.size(), log.sent_readings.size());
  for (size_t i = 0; i < r.readings.size(); ++i)
    ExpectSameReading(r.readings[i], log.sent_readings[i]);
  EXPECT_EQ(r.readings.back().epoch, 1u);
}

TEST(MockMcu, StallRaisesAStallErrorWithinTheDeadline) {
  MockMcuOptions options;
  options.faults.push_back({McuFaultKind::kStall, 300, /*stall_ms=*/-1});
  MockMcu mock(options, Synthetic(5));
  mock.Start();
  auto sensor = hall_mcu::OpenHallMcu(
      DriverOptions(mock.device_path(), /*stall_ms=*/150, /*command_ms=*/150));
  ASSERT_TRUE(sensor->StartStreaming().ok);
  Received r = ReadAll(*sensor);
  EXPECT_EQ(r.last, ReadStatus::kStall);
  EXPECT_FALSE(r.end_of_data);
  EXPECT_EQ(sensor->counters().stalls, 1u);
  const MockMcuLog log = mock.Log();
  EXPECT_EQ(log.stalls, 1u);
  EXPECT_EQ(r.readings.size(), log.sent_readings.size());
  // A stalled MCU does not answer commands either: the command fails by its deadline.
  EXPECT_FALSE(sensor->RequestStatus().ok);
  mock.Stop();
}

TEST(MockMcu, ClosedDeviceIsReportedNotHung) {
  auto mock = std::make_unique<MockMcu>(MockMcuOptions{}, Synthetic(1));
  mock->Start();
  auto sensor = hall_mcu::OpenHallMcu(DriverOptions(mock->device_path()));
  mock.reset();  // the MCU is unplugged
  HallBatch batch;
  hall_mcu::ReadResult res;
  do {
    batch.clear();
    res = sensor->Read(&batch);
  } while (res.status == ReadStatus::kOk);
  EXPECT_EQ(res.status, ReadStatus::kClosed) << res.message;
}

TEST(MockMcu, MargBoardStreamsMargReadings) {
  MockMcu mock({}, Synthetic(0.5, SyntheticMode::kMarg));
  mock.Start();
  auto sensor = hall_mcu::OpenHallMcu(DriverOptions(mock.device_path()));
  ASSERT_TRUE(sensor->StartStreaming().ok);
  Received r = ReadAll(*sensor);
  ASSERT_TRUE(r.end_of_data);
  EXPECT_EQ(r.marg.size(), 500u);
  EXPECT_EQ(r.marg.size(), mock.Log().sent_marg);
  EXPECT_NEAR(r.marg[0].accel_g[2], 0.995, 0.05);
  EXPECT_NEAR(r.marg[0].mag_uT[2], -43.0, 10.0);
}

TEST(MockMcu, ReplaysARecordedSession) {
  dataset::HallRecording rec;
  for (int i = 0; i < 300; ++i) {
    rec.readings.push_back({1000.0 * i + 17, 0.150 * i, -0.150 * i, 0.242 * (i % 7)});
  }
  rec.clock_edges_us = {50, 100050, 200050};
  MockMcu mock({}, std::make_unique<ReplaySource>(rec));
  mock.Start();
  auto sensor = hall_mcu::OpenHallMcu(DriverOptions(mock.device_path()));
  ASSERT_TRUE(sensor->StartStreaming().ok);
  Received r = ReadAll(*sensor);
  ASSERT_TRUE(r.end_of_data);
  ASSERT_EQ(r.readings.size(), 300u);
  for (int i = 0; i < 300; ++i) {
    EXPECT_EQ(r.readings[i].mcu_time_us, rec.readings[i].mcu_time_us);
    // Values on the 0.150 / 0.242 uT grid of gain 7, res 0 come back to rounding error.
    EXPECT_NEAR(r.readings[i].bx_uT, rec.readings[i].bx_uT, 1e-9);
    EXPECT_NEAR(r.readings[i].by_uT, rec.readings[i].by_uT, 1e-9);
    EXPECT_NEAR(r.readings[i].bz_uT, rec.readings[i].bz_uT, 1e-9);
  }
  ASSERT_EQ(r.edges.size(), 3u);
  EXPECT_EQ(r.edges[2].mcu_time_us, 200050);
}

TEST(SyntheticSource, IsDeterministicForASeed) {
  SyntheticSource a(SyntheticSourceOptions{}), b(SyntheticSourceOptions{});
  for (int i = 0; i < 1000; ++i) {
    auto ea = a.Next(), eb = b.Next();
    ASSERT_TRUE(ea && eb);
    EXPECT_EQ(ea->time_us, eb->time_us);
    EXPECT_EQ(ea->field_uT, eb->field_uT);
  }
}

}  // namespace
}  // namespace msmcal::sim
