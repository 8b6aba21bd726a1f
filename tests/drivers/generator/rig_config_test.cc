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
  EXPECT_DOUBLE_EQ(c.signals.fast.frequency_hz, 1230.0);
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
  const std::string text = Replace(ExampleText(), "frequency_hz: 1230,", "frequency_hz: fast,");
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
  c = ParseRigGeneratorConfig(Replace(ExampleText(), "frequency_hz: 1230", "frequency_hz: 1500"),
                              "rig.yaml");
  EXPECT_EQ(c.Validate(),
            "generators.unit1.ch1 (fast_coil): frequency_hz = 1500 outside the window [1100, "
            "1350] Hz");
  c = ParseRigGeneratorConfig(Replace(ExampleText(), "port: 15025", "port: 0"), "rig.yaml");
  EXPECT_EQ(c.Validate(), "generators.unit1.port = 0: must be in [1, 65535]");
  c = ParseRigGeneratorConfig(
      Replace(ExampleText(), "pulse_width_s: 1.0e-6", "pulse_width_s: 1.0e-4"), "rig.yaml");
  EXPECT_NE(c.Validate().find("max_duty"), std::string::npos) << c.Validate();
}

}  // namespace
}  // namespace msmcal::gen
