#include "drivers/hall_mcu/hall_mcu_config.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

namespace msmcal::hall_mcu {
namespace {

TEST(HallMcuConfig, ReadsTheRigConfiguration) {
  const char* src = std::getenv("MSMCAL_SOURCE_DIR");
  const std::filesystem::path root = src != nullptr ? src : MSMCAL_TEST_SOURCE_DIR;
  const HallMcuConfig c = LoadHallMcuConfig(root / "config" / "rig.yaml");
  EXPECT_EQ(c.link.device, "/dev/ttyACM0");
  EXPECT_EQ(c.link.baud_rate, 921600u);
  EXPECT_EQ(c.link.stall_timeout_ms, 500);
  EXPECT_EQ(c.rate_hz, 1000);
  EXPECT_EQ(c.sensor.gain_sel, 7);
}

TEST(HallMcuConfig, DefaultsForMissingKeys) {
  const HallMcuConfig c = ParseHallMcuConfig("hall_mcu: {device: /dev/ttyUSB3}\n", "t.yaml");
  EXPECT_EQ(c.link.device, "/dev/ttyUSB3");
  EXPECT_EQ(c.link.stall_timeout_ms, HallMcuOptions{}.stall_timeout_ms);
  EXPECT_EQ(c.sensor, SensorSettings{});
}

std::string ErrorOf(const std::string& yaml) {
  try {
    ParseHallMcuConfig(yaml, "rig.yaml");
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(HallMcuConfig, ErrorsNameFileLineAndField) {
  EXPECT_EQ(ErrorOf("generators: {}\n"), "rig.yaml: hall_mcu: missing section");
  EXPECT_EQ(ErrorOf("hall_mcu:\n  device: x\n  bogus: 1\n"),
            "rig.yaml:3: hall_mcu.bogus: unknown key");
  EXPECT_EQ(ErrorOf("hall_mcu:\n  rate_hz: fast\n"),
            "rig.yaml:2: hall_mcu.rate_hz: has the wrong type");
  EXPECT_EQ(ErrorOf("hall_mcu:\n  sensor: {gain_sel: 9}\n"),
            "rig.yaml:2: hall_mcu.sensor: SensorSettings.gain_sel = 9: violated constraint 0 <= "
            "gain_sel <= 7");
  EXPECT_NE(ErrorOf("hall_mcu:\n  stall_timeout_ms: 0\n").find("stall_timeout_ms = 0"),
            std::string::npos);
}

}  // namespace
}  // namespace msmcal::hall_mcu
