#include "drivers/camera/device_clock.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace msmcal::camera {
namespace {

FrameInfo At(int64_t device_ns, int64_t host_ns) {
  FrameInfo f;
  f.device_timestamp_ns = device_ns;
  f.host_timestamp_ns = host_ns;
  return f;
}

// Host = device + 5 s + a delivery delay that varies (40..900 ms): the offset is the fastest
// frame's, and a device instant maps to host time late by that frame's delay, never early.
TEST(DeviceClockMapTest, TheOffsetIsTheFastestFramesAndMappedTimesAreNeverEarly) {
  const int64_t offset = 5'000'000'000;
  const std::vector<int64_t> delay_ms = {900, 300, 40, 650, 120, 75};
  DeviceClockMap map;
  EXPECT_FALSE(map.HostNs(0).has_value());
  for (size_t i = 0; i < delay_ms.size(); ++i) {
    const int64_t device = static_cast<int64_t>(i) * 250'000'000 + 1;
    map.Observe(At(device, device + offset + delay_ms[i] * 1'000'000));
  }
  ASSERT_TRUE(map.OffsetNs().has_value());
  EXPECT_EQ(*map.OffsetNs(), offset + 40'000'000);
  EXPECT_EQ(*map.HostNs(7'000'000'000), 7'000'000'000 + offset + 40'000'000);
  EXPECT_EQ(map.frames(), delay_ms.size());
}

// Frames without a device timestamp (0: the driver has none) leave the estimate alone.
TEST(DeviceClockMapTest, FramesWithoutADeviceTimestampAreIgnored) {
  DeviceClockMap map;
  map.Observe(At(0, 123));
  EXPECT_FALSE(map.OffsetNs().has_value());
  map.Observe(At(1000, 1500));
  map.Observe(At(0, 99));
  EXPECT_EQ(*map.OffsetNs(), 500);
  EXPECT_EQ(map.frames(), 1u);
}

// The minimum is over the last `window` frames: a device clock running 200 ppm slow is followed.
TEST(DeviceClockMapTest, TheWindowFollowsADriftingDeviceClock) {
  DeviceClockMap map(/*window=*/8);
  int64_t delta = 0;
  for (int i = 0; i < 100; ++i) {
    const int64_t host = int64_t{i} * 1'000'000'000;
    const int64_t device = host - host / 5000;  // 200 ppm slow
    delta = host - device;
    map.Observe(At(device + 1, host + 1 + 10'000'000));  // 10 ms delivery
  }
  EXPECT_NEAR(static_cast<double>(*map.OffsetNs()), static_cast<double>(delta + 10'000'000),
              8 * 200'000.0);  // within the window's drift: 8 frames x 200 us
}

// A device clock that restarts (the camera re-opened) starts the estimate again instead of
// mapping every later frame seconds early.
TEST(DeviceClockMapTest, ADeviceClockResetStartsTheEstimateAgain) {
  DeviceClockMap map(/*window=*/64, /*reset_ns=*/10'000'000'000);
  map.Observe(At(100'000'000'000, 100'000'000'000 + 20'000'000));
  map.Observe(At(100'250'000'000, 100'250'000'000 + 30'000'000));
  // The camera restarts at device time 1 ms while the host goes on.
  map.Observe(At(1'000'000, 100'500'000'000 + 25'000'000));
  EXPECT_EQ(map.frames(), 1u);
  EXPECT_EQ(*map.OffsetNs(), 100'500'000'000 + 25'000'000 - 1'000'000);
}

}  // namespace
}  // namespace msmcal::camera
