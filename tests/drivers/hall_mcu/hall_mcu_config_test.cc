#include "drivers/hall_mcu/hall_mcu_config.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

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

namespace msmcal::hall_mcu {
namespace {

// A pseudo-terminal stands for the MCU's tty. Every serial option is checked on its own: an
// unsupported baud rate used to be overwritten by the success of the options after it.
TEST(HallMcuSerial, AnOptionTheTtyRefusesIsReportedEvenIfLaterOnesSucceed) {
  const int master = posix_openpt(O_RDWR | O_NOCTTY);
  ASSERT_GE(master, 0);
  ASSERT_EQ(grantpt(master), 0);
  ASSERT_EQ(unlockpt(master), 0);
  HallMcuOptions o;
  o.device = ptsname(master);
  o.baud_rate = 12345;  // not a termios rate
  try {
    OpenHallMcu(o);
    ADD_FAILURE() << "expected the baud rate to be refused";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("baud_rate 12345"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(o.device), std::string::npos) << e.what();
  }
  o.baud_rate = 921600;
  EXPECT_NO_THROW(OpenHallMcu(o));
  close(master);
}

}  // namespace
}  // namespace msmcal::hall_mcu
