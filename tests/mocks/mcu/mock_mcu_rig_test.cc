// The mock MCU streaming the rig simulator's Hall model through a real pty to the real driver.
#include <gtest/gtest.h>

#include <cmath>

#include "drivers/hall_mcu/hall_sensor.h"
#include "mocks/mcu/mock_mcu.h"
#include "mocks/mcu/rig_hall_source.h"

namespace msmcal::sim {
namespace {

TEST(RigHallSource, StreamsTheRigRecordingThroughThePty) {
  SimOptions sim;
  sim.hall.background_duration_s = 3.0;
  const uint64_t seed = 5;
  HallModel model(sim);
  const dataset::HallRecording truth =
      HallSampler(model, HallRecordingKind::kBackground, seed).Collect();
  ASSERT_GT(truth.readings.size(), 2900u);

  MockMcu mock({}, std::make_unique<RigHallSource>(sim, HallRecordingKind::kBackground, seed));
  mock.Start();
  hall_mcu::HallMcuOptions o;
  o.device = mock.device_path();
  o.stall_timeout_ms = 2000;
  auto sensor = hall_mcu::OpenHallMcu(o);
  ASSERT_TRUE(sensor->StartStreaming().ok);
  std::vector<hall_mcu::HallSample> got;
  std::vector<hall_mcu::ClockEdge> edges;
  hall_mcu::HallBatch batch;
  while (!batch.end_of_data) {
    batch.clear();
    ASSERT_EQ(sensor->Read(&batch).status, hall_mcu::ReadStatus::kOk);
    got.insert(got.end(), batch.readings.begin(), batch.readings.end());
    edges.insert(edges.end(), batch.edges.begin(), batch.edges.end());
  }
  ASSERT_EQ(got.size(), truth.readings.size());
  const double lsb_xy = hall_mcu::SensitivityUtPerLsb(hall_mcu::Axis::kX, 7, 0);
  const double lsb_z = hall_mcu::SensitivityUtPerLsb(hall_mcu::Axis::kZ, 7, 0);
  for (size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].mcu_time_us, truth.readings[i].mcu_time_us);
    // Quantised by the sensor's LSB: within half an LSB of the simulated field.
    ASSERT_LE(std::abs(got[i].bx_uT - truth.readings[i].bx_uT), 0.5 * lsb_xy + 1e-9);
    ASSERT_LE(std::abs(got[i].by_uT - truth.readings[i].by_uT), 0.5 * lsb_xy + 1e-9);
    ASSERT_LE(std::abs(got[i].bz_uT - truth.readings[i].bz_uT), 0.5 * lsb_z + 1e-9);
  }
  ASSERT_EQ(edges.size(), truth.clock_edges_us.size());
  for (size_t i = 0; i < edges.size(); ++i)
    EXPECT_EQ(edges[i].mcu_time_us, truth.clock_edges_us[i]);
  EXPECT_EQ(sensor->counters().readings_lost, 0u);
}

}  // namespace
}  // namespace msmcal::sim
