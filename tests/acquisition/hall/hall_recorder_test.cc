// The Hall recorder against the mock MCU on a pty, and against an in-memory fake sensor for the
// queue behaviour. No sleeps: the slow sink blocks on a latch the test releases.
#include "acquisition/hall/hall_recorder.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <condition_variable>
#include <filesystem>
#include <mutex>

#include "acquisition/hall/hall_csv_writer.h"
#include "mocks/mcu/mock_mcu.h"

namespace msmcal::acquisition {
namespace {

using hall_mcu::HallBatch;

std::unique_ptr<sim::McuDataSource> Synthetic(double seconds) {
  sim::SyntheticSourceOptions o;
  o.duration_s = seconds;
  return std::make_unique<sim::SyntheticSource>(o);
}

hall_mcu::HallMcuOptions DriverOptions(const std::string& device) {
  hall_mcu::HallMcuOptions o;
  o.device = device;
  o.stall_timeout_ms = 2000;
  return o;
}

struct Collected {
  std::mutex mu;
  std::vector<hall_mcu::HallSample> readings;
  std::vector<hall_mcu::ClockEdge> edges;
  HallBatchSink Sink() {
    return [this](const HallBatch& b) {
      std::lock_guard lock(mu);
      readings.insert(readings.end(), b.readings.begin(), b.readings.end());
      edges.insert(edges.end(), b.edges.begin(), b.edges.end());
    };
  }
};

// The acceptance test through the recorder: 60 s of simulated 1 kHz data over a real pty,
// faster than real time; every reading the mock sent reaches the sink, in order, same values.
TEST(HallRecorder, RecordsSixtySecondsAtOneKilohertzCompleteAndInOrder) {
  sim::MockMcu mock({}, Synthetic(60));
  mock.Start();
  auto sensor = hall_mcu::OpenHallMcu(DriverOptions(mock.device_path()));
  Collected got;
  HallRecorderOptions options;
  options.rate_hz = 1000;
  options.settings = hall_mcu::SensorSettings{.gain_sel = 5, .res_x = 1, .res_y = 1, .res_z = 0};
  HallRecorder recorder(*sensor, got.Sink(), options);
  recorder.Start();
  const HallRecorderResult result = recorder.Wait();
  EXPECT_EQ(result.end, RecorderEnd::kEndOfData) << result.message;
  const sim::MockMcuLog log = mock.Log();
  ASSERT_EQ(got.readings.size(), 60000u);
  ASSERT_EQ(got.readings.size(), log.sent_readings.size());
  for (size_t i = 0; i < got.readings.size(); ++i) {
    ASSERT_EQ(got.readings[i].mcu_time_us, log.sent_readings[i].mcu_time_us);
    ASSERT_EQ(got.readings[i].bx_uT, log.sent_readings[i].bx_uT);
    ASSERT_EQ(got.readings[i].bz_uT, log.sent_readings[i].bz_uT);
  }
  EXPECT_EQ(got.readings[0].gain_sel, 5);
  EXPECT_EQ(got.edges.size(), 120u);
  EXPECT_EQ(result.counts.readings_delivered, 60000u);
  EXPECT_EQ(result.counts.driver.readings, 60000u);
  EXPECT_EQ(result.counts.driver.readings_lost, 0u);
  EXPECT_EQ(result.counts.batches_dropped, 0u);
  EXPECT_NEAR(result.counts.seconds_recorded, 59.999, 1e-9);
}

TEST(HallRecorder, StopsAtTheDurationLimitExactly) {
  sim::MockMcu mock({}, Synthetic(10));
  mock.Start();
  auto sensor = hall_mcu::OpenHallMcu(DriverOptions(mock.device_path()));
  Collected got;
  HallRecorderOptions options;
  options.max_seconds = 2.5;
  HallRecorder recorder(*sensor, got.Sink(), options);
  recorder.Start();
  const HallRecorderResult result = recorder.Wait();
  EXPECT_EQ(result.end, RecorderEnd::kDuration);
  ASSERT_EQ(got.readings.size(), 2500u);  // t = 0 .. 2.499 s
  EXPECT_EQ(got.readings.back().mcu_time_us, 2499000);
  ASSERT_EQ(got.edges.size(), 5u);  // 0.000123 + k 0.5 s < 2.499 s
  EXPECT_LT(got.edges.back().mcu_time_us, 2500000);
}

TEST(HallRecorder, RestartsStreamingAfterAnMcuResetAndCountsLosses) {
  sim::MockMcuOptions mock_options;
  mock_options.faults = {{sim::McuFaultKind::kFlipBit, 500},
                         {sim::McuFaultKind::kReset, 3000},
                         {sim::McuFaultKind::kDropByte, 4500}};
  sim::MockMcu mock(mock_options, Synthetic(6));
  mock.Start();
  auto sensor = hall_mcu::OpenHallMcu(DriverOptions(mock.device_path()));
  Collected got;
  HallRecorder recorder(*sensor, got.Sink(), HallRecorderOptions{});
  recorder.Start();
  const HallRecorderResult result = recorder.Wait();
  EXPECT_EQ(result.end, RecorderEnd::kEndOfData) << result.message;
  const sim::MockMcuLog log = mock.Log();
  EXPECT_EQ(result.counts.driver.resets, 1u);
  EXPECT_EQ(result.counts.driver.readings_lost, log.damaged_reading_seqs.size());
  EXPECT_EQ(result.counts.driver.clock_edges_lost, log.damaged_edge_seqs.size());
  EXPECT_EQ(got.readings.size(), log.sent_readings.size());
  EXPECT_EQ(got.readings.back().epoch, 1u);
}

// A sensor that yields a fixed number of one-reading batches, then stalls.
class FakeSensor final : public hall_mcu::HallSensor {
 public:
  explicit FakeSensor(int batches) : batches_(batches) {}
  hall_mcu::CommandResult Identify(hall_mcu::DeviceInfo*) override { return {}; }
  hall_mcu::CommandResult StartStreaming() override { return {}; }
  hall_mcu::CommandResult StopStreaming() override { return {}; }
  hall_mcu::CommandResult SetRate(uint16_t) override { return {}; }
  hall_mcu::CommandResult SetSensor(const hall_mcu::SensorSettings&) override { return {}; }
  hall_mcu::CommandResult RequestStatus() override { return {}; }
  hall_mcu::ReadResult Read(HallBatch* batch) override {
    if (sent_ == batches_) {
      ++counters_.stalls;
      return {hall_mcu::ReadStatus::kStall, "fake stall"};
    }
    hall_mcu::HallSample s;
    s.seq = static_cast<uint32_t>(sent_);
    s.mcu_time_us = 1000 * sent_++;
    batch->readings.push_back(s);
    ++counters_.readings;
    return {};
  }
  const hall_mcu::HallCounters& counters() const override { return counters_; }

 private:
  int batches_;
  int sent_ = 0;
  hall_mcu::HallCounters counters_;
};

TEST(HallRecorder, SlowSinkNeverBlocksTheReaderAndOverflowIsCounted) {
  FakeSensor sensor(100);
  std::mutex mu;
  std::condition_variable cv;
  bool release = false;
  size_t delivered = 0;
  HallRecorderOptions options;
  options.queue_capacity = 10;
  options.control_streaming = false;
  HallRecorder recorder(
      sensor,
      [&](const HallBatch& b) {
        std::unique_lock lock(mu);
        cv.wait(lock, [&] { return release; });  // the sink is stuck until the reader is done
        delivered += b.readings.size();
      },
      options);
  recorder.Start();
  // The reader finishes (stall) while the sink is still blocked on its first batch.
  HallRecorderCounts counts;
  do {
    counts = recorder.Counts();
  } while (counts.driver.stalls == 0);
  {
    std::lock_guard lock(mu);
    release = true;
  }
  cv.notify_all();
  const HallRecorderResult result = recorder.Wait();
  EXPECT_EQ(result.end, RecorderEnd::kStall);
  EXPECT_EQ(result.counts.readings_delivered + result.counts.readings_dropped, 100u);
  EXPECT_GE(result.counts.batches_dropped, 100u - 11u);
  EXPECT_EQ(delivered, result.counts.readings_delivered);
}

// Disk full on hall/: the CSV writer's files are links to /dev/full, so the first write in the
// sink thread throws ENOSPC. The recorder catches it (no std::terminate), stops the reader and
// reports the error; nothing after the failure counts as delivered.
TEST(HallRecorder, ASinkThatThrowsStopsTheRecordingAndIsReported) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(::testing::TempDir()) / "hall_recorder_full";
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::create_symlink("/dev/full", dir / "actual.csv");
  fs::create_symlink("/dev/full", dir / "actual_clock.csv");
  acquisition::HallCsvWriter writer(dir / "actual.csv");
  FakeSensor sensor(1000000);  // would run for a long time: only the failure can end it early
  HallRecorderOptions options;
  options.control_streaming = false;
  HallRecorder recorder(
      sensor, [&](const HallBatch& b) { writer.Write(b); }, options);
  recorder.Start();
  const HallRecorderResult result = recorder.Wait();
  EXPECT_EQ(result.end, RecorderEnd::kSinkFailed) << result.message;
  EXPECT_NE(result.message.find("No space left on device"), std::string::npos) << result.message;
  EXPECT_NE(result.message.find("actual.csv"), std::string::npos) << result.message;
  EXPECT_EQ(recorder.SinkError().empty(), false);
  EXPECT_EQ(result.counts.readings_delivered, 0u);
  EXPECT_GE(result.counts.readings_dropped, 1u);
  EXPECT_LT(result.counts.driver.readings, 1000000u);
}

// A sink call that never returns: Wait() is bounded and says so instead of blocking forever.
TEST(HallRecorder, WaitGivesUpOnAHungSink) {
  FakeSensor sensor(3);
  HallRecorderOptions options;
  options.control_streaming = false;
  options.sink_timeout_ms = 200;  // failure bound, not a synchronisation
  // The sink blocks on a pipe nobody writes to until the test ends; it owns its end of the pipe.
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  auto read_end = std::make_shared<int>(fds[0]);
  HallRecorder recorder(
      sensor,
      [read_end](const HallBatch&) {
        char c;
        (void)!read(*read_end, &c, 1);
      },
      options);
  recorder.Start();
  const HallRecorderResult result = recorder.Wait();
  EXPECT_EQ(result.end, RecorderEnd::kSinkHung) << result.message;
  EXPECT_NE(result.message.find("sink_timeout_ms = 200"), std::string::npos) << result.message;
  // Release the abandoned thread (it returns into the recorder's shared state and exits).
  ASSERT_EQ(write(fds[1], "xxx", 3), 3);
  close(fds[1]);
}

TEST(HallRecorderOptions, ValidateNamesTheField) {
  HallRecorderOptions o;
  o.queue_capacity = 0;
  EXPECT_NE(o.Validate().find("queue_capacity = 0"), std::string::npos);
  o = {};
  o.max_seconds = -1;
  EXPECT_NE(o.Validate().find("max_seconds"), std::string::npos);
  o = {};
  o.sink_timeout_ms = 0;
  EXPECT_NE(o.Validate().find("sink_timeout_ms = 0"), std::string::npos);
}

}  // namespace
}  // namespace msmcal::acquisition
