#include "drivers/generator/rig_config.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "test_rig.h"

namespace msmcal::gen {
namespace {

std::string ExampleText() {
  std::ifstream in(testing::SourceDir() + "/config/rig.yaml");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t p = text.find(from);
  EXPECT_NE(p, std::string::npos) << from;
  if (p != std::string::npos) text.replace(p, from.size(), to);
  return text;
}

TEST(RigConfigTest, ExampleLoadsAndValidates) {
  const RigGeneratorConfig c = LoadRigGeneratorConfig(testing::SourceDir() + "/config/rig.yaml");
  EXPECT_EQ(c.Validate(), "");
  EXPECT_EQ(c.unit1.name, "unit1");
  EXPECT_EQ(c.unit1.limits[0].role, "fast_coil");
  EXPECT_DOUBLE_EQ(c.signals.fast.frequency_hz, 205.0);  // the twin's mirror (config/sim.yaml)
  EXPECT_TRUE(std::isinf(c.signals.laser.load_ohm));
  EXPECT_DOUBLE_EQ(c.unit2.limits[0].max_duty, 0.01);
}

TEST(RigConfigTest, UnknownKeyNamesFileLineAndField) {
  const std::string text =
      Replace(ExampleText(), "connect_timeout_ms: 3000", "conect_timeout_ms: 3000");
  try {
    ParseRigGeneratorConfig(text, "rig.yaml");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("rig.yaml:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("generators.unit1.conect_timeout_ms: unknown key"),
              std::string::npos)
        << e.what();
  }
}

TEST(RigConfigTest, BadNumberNamesField) {
  const std::string text = Replace(ExampleText(), "frequency_hz: 205,", "frequency_hz: fast,");
  try {
    ParseRigGeneratorConfig(text, "rig.yaml");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("generators.signals.drive.fast.frequency_hz: must be a "
                                         "number, got 'fast'"),
              std::string::npos)
        << e.what();
  }
}

TEST(RigConfigTest, DriveOutsideLimitsIsRefusedByValidate) {
  RigGeneratorConfig c = ParseRigGeneratorConfig(
      Replace(ExampleText(), "amplitude_vpp: 2.0", "amplitude_vpp: 10.0"), "rig.yaml");
  EXPECT_EQ(c.Validate(),
            "generators.unit1.ch1 (fast_coil): amplitude_vpp = 10 outside the limit [0, 4] Vpp");
  c = ParseRigGeneratorConfig(Replace(ExampleText(), "frequency_hz: 205", "frequency_hz: 300"),
                              "rig.yaml");
  EXPECT_EQ(c.Validate(),
            "generators.unit1.ch1 (fast_coil): frequency_hz = 300 outside the window [195, "
            "215] Hz");
  c = ParseRigGeneratorConfig(Replace(ExampleText(), "port: 15025", "port: 0"), "rig.yaml");
  EXPECT_EQ(c.Validate(), "generators.unit1.port = 0: must be in [1, 65535]");
  c = ParseRigGeneratorConfig(
      Replace(ExampleText(), "pulse_width_s: 1.0e-6", "pulse_width_s: 1.0e-4"), "rig.yaml");
  EXPECT_NE(c.Validate().find("max_duty"), std::string::npos) << c.Validate();
}

// Limits are data of the rig file: finite, inside what a 33520B delivers into the configured
// load, one role per channel, and a laser duty limit that keeps the pulses sparse.
TEST(RigConfigTest, AnInfiniteLimitIsRefusedAtItsLine) {
  const std::string text = Replace(ExampleText(), "max_vpp: 4.0", "max_vpp: .inf");
  try {
    ParseRigGeneratorConfig(text, "rig.yaml");
    FAIL() << "an infinite limit must be refused";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("rig.yaml:17: generators.unit1.channels.1.max_vpp = .inf: "
                                         "must be a finite number (inf is accepted only for "
                                         "load_ohm: high impedance)"),
              std::string::npos)
        << e.what();
  }
  // inf stays the spelling of high impedance for loads.
  EXPECT_TRUE(
      std::isinf(ParseRigGeneratorConfig(ExampleText(), "rig.yaml").signals.laser.load_ohm));
}

TEST(RigConfigTest, LimitsBeyondThe33520bAreRefused) {
  RigGeneratorConfig c =
      ParseRigGeneratorConfig(Replace(ExampleText(), "max_vpp: 4.0", "max_vpp: 1e6"), "rig.yaml");
  EXPECT_EQ(c.Validate(),
            "generators.unit1.channels.1.limits.max_vpp = 1000000: must be finite, in [0, 20] Vpp "
            "(33520B open-circuit maximum)");
  // 12 Vpp is possible into high-Z but not into the coils' 50 ohm (10 Vpp).
  c = ParseRigGeneratorConfig(Replace(ExampleText(), "max_vpp: 4.0", "max_vpp: 12"), "rig.yaml");
  EXPECT_EQ(c.Validate(),
            "generators.unit1.channels.1.limits.max_vpp = 12: above what the 33520B delivers "
            "into 50 ohm (10 Vpp)");
  c = ParseRigGeneratorConfig(
      Replace(ExampleText(), "max_frequency_hz: 215", "max_frequency_hz: 4e7"), "rig.yaml");
  EXPECT_NE(c.Validate().find("generators.unit1.channels.1.limits.max_frequency_hz = 40000000"),
            std::string::npos)
      << c.Validate();
  c = ParseRigGeneratorConfig(
      Replace(ExampleText(), "max_abs_offset_v: 1.65", "max_abs_offset_v: 12"), "rig.yaml");
  EXPECT_NE(c.Validate().find("generators.unit2.channels.2.limits.max_abs_offset_v = 12"),
            std::string::npos)
      << c.Validate();
}

TEST(RigConfigTest, TwoChannelsWithOneRoleAreAConfigurationError) {
  const RigGeneratorConfig c = ParseRigGeneratorConfig(
      Replace(ExampleText(), "role: slow_coil", "role: fast_coil"), "rig.yaml");
  EXPECT_EQ(c.Validate(),
            "generators.unit1.channels.2.role = 'fast_coil': another channel has the same role "
            "(each channel drives one thing)");
}

TEST(RigConfigTest, ALaserDutyLimitOfNinetyPercentIsRefused) {
  RigGeneratorConfig c =
      ParseRigGeneratorConfig(Replace(ExampleText(), "max_frequency_hz: 1000, max_duty: 0.01",
                                      "max_frequency_hz: 1000, max_duty: 0.9"),
                              "rig.yaml");
  EXPECT_EQ(c.Validate(),
            "generators.unit2.channels.1.max_duty = 0.9: the laser trigger's duty limit must be "
            "<= 0.1");
  c = ParseRigGeneratorConfig(Replace(ExampleText(), "      max_duty: 0.01", "      max_duty: 0.9"),
                              "rig.yaml");
  EXPECT_EQ(c.Validate(),
            "generators.signals.trigger.max_duty = 0.9: must be <= 0.1 (sparse laser pulses)");
}

TEST(CheckLimitsTest, ASetupBeyondTheInstrumentIsRefusedWhateverTheLimits) {
  ChannelLimits wide{"test", 20.0, 10.0, 0.0, 30e6, 1.0};
  ChannelSetup s;
  s.amplitude_vpp = 12.0;
  s.load_ohm = 50.0;
  EXPECT_EQ(CheckLimits("u.ch1", s, wide),
            "u.ch1 (test): amplitude_vpp = 12 above the 33520B's 10 Vpp into 50 ohm");
  s.load_ohm = kHighZ;
  EXPECT_EQ(CheckLimits("u.ch1", s, wide), "");
  s.offset_v = 5.0;  // 5 + 12/2 > 10 V
  EXPECT_NE(CheckLimits("u.ch1", s, wide).find("|offset_v| + amplitude_vpp/2 = 11"),
            std::string::npos);
  s.offset_v = 0.0;
  s.load_ohm = 0.5;
  EXPECT_NE(CheckLimits("u.ch1", s, wide).find("load_ohm = 0.5"), std::string::npos);
}

}  // namespace
}  // namespace msmcal::gen
