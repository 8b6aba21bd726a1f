#include "sessions/rig/rig_file.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

namespace msmcal::rig {
namespace {

std::filesystem::path ExampleFile() {
  const char* src = std::getenv("MSMCAL_SOURCE_DIR");
  return std::filesystem::path(src != nullptr ? src : MSMCAL_TEST_SOURCE_DIR) / "config" /
         "rig.yaml";
}

std::string ExampleText() {
  std::ifstream in(ExampleFile());
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

// The 1-based line of the first occurrence of `needle` in the example.
int LineOf(const std::string& text, const std::string& needle) {
  const size_t p = text.find(needle);
  EXPECT_NE(p, std::string::npos) << needle;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + p, '\n'));
}

std::string ErrorOf(const std::string& text) {
  try {
    ParseRigFile(text, "rig.yaml");
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(accepted)";
}

// The example is the twin's default rig (config/sim.yaml), every section read.
TEST(RigFileTest, TheExampleReadsCompletely) {
  const RigFile r = LoadRigFile(ExampleFile());
  EXPECT_EQ(r.origin, ExampleFile().string());
  EXPECT_EQ(r.text, ExampleText());
  EXPECT_DOUBLE_EQ(r.generators.signals.fast.frequency_hz, 205);
  EXPECT_DOUBLE_EQ(r.generators.signals.slow.frequency_hz, 5);
  EXPECT_DOUBLE_EQ(r.generators.signals.slow.amplitude_vpp, 4);
  EXPECT_DOUBLE_EQ(r.generators.unit1.limits[0].min_frequency_hz, 195);
  EXPECT_DOUBLE_EQ(r.generators.unit1.limits[0].max_frequency_hz, 215);
  EXPECT_EQ(r.generators.unit2.link.port, 15026);
  EXPECT_EQ(r.camera.kind, CameraKind::kGige);
  EXPECT_EQ(r.camera.address, "127.0.0.1");
  EXPECT_EQ(r.camera.OpenString(), "127.0.0.1");
  EXPECT_DOUBLE_EQ(r.camera.frame_rate_hz, 4);
  EXPECT_DOUBLE_EQ(r.camera.exposure_us, 220000);
  EXPECT_EQ(r.camera.model.width, 2448);
  EXPECT_EQ(r.camera.model.height, 2048);
  EXPECT_DOUBLE_EQ(r.camera.model.fx, 2000);
  EXPECT_DOUBLE_EQ(r.camera.model.cy, 1023.5);
  EXPECT_DOUBLE_EQ(r.camera.model.distortion[0], -0.08);
  EXPECT_DOUBLE_EQ(r.camera.model.distortion[3], -3.0e-4);
  EXPECT_EQ(r.camera.model.Validate(), "");
  EXPECT_EQ(r.hall_mcu.link.device, "/dev/ttyACM0");
  EXPECT_EQ(r.hall_mcu.rate_hz, 1000);
  EXPECT_EQ(r.world_board.cols, 23);
  EXPECT_EQ(r.world_board.rows, 28);
  EXPECT_EQ(r.sliding_board.cols, 13);
  EXPECT_EQ(r.sliding_board.rows, 8);
  EXPECT_DOUBLE_EQ(r.sliding_board.square_mm, 10);
  EXPECT_EQ(r.beams.count, 3);
  EXPECT_EQ(r.beams.validate_ids, std::vector<int>{3});
  EXPECT_EQ(r.sliding_plate.poses, 7);
  EXPECT_DOUBLE_EQ(r.sliding_plate.DistanceMm(0), 35);
  EXPECT_DOUBLE_EQ(r.sliding_plate.DistanceMm(6), 100);
  EXPECT_DOUBLE_EQ(r.sliding_plate.TiltDeg(1), -12);
  EXPECT_EQ(r.step1.exposures, 3);
  EXPECT_TRUE(r.step1.identification_frames);
  EXPECT_TRUE(r.step1.background_frames);
  EXPECT_EQ(r.step2.neutral_frames, 2);
  EXPECT_EQ(r.step2.fast_only_frames, 3);
  EXPECT_EQ(r.step2.fast_only_triggers_per_frame, 4);
  EXPECT_EQ(r.step2.scan_triggers_per_frame, 3);
  EXPECT_DOUBLE_EQ(r.step2.frame_min_separation, 0.5);
  EXPECT_DOUBLE_EQ(r.step2.hall_background_s, 12);
  EXPECT_DOUBLE_EQ(r.step2.hall_actual_min_s, 15);
}

TEST(RigFileTest, AV4l2CameraNeedsADeviceAndNoAddress) {
  const std::string v4l2 = Replace(ExampleText(), "  kind: gige\n  address: 127.0.0.1",
                                   "  kind: v4l2\n  device: /dev/video2");
  const RigFile r = ParseRigFile(v4l2, "rig.yaml");
  EXPECT_EQ(r.camera.kind, CameraKind::kV4l2);
  EXPECT_EQ(r.camera.OpenString(), "v4l2:/dev/video2");
  const int line = LineOf(ExampleText(), "  kind: gige");
  EXPECT_EQ(ErrorOf(Replace(ExampleText(), "  address: 127.0.0.1", "  #ddress: 127.0.0.1")),
            "rig.yaml:" + std::to_string(line) + ": camera.address: missing");
  EXPECT_EQ(ErrorOf(Replace(v4l2, "  device: /dev/video2", "  device: video2")),
            "rig.yaml:" + std::to_string(line + 1) +
                ": camera.device = 'video2': must be an absolute path");
  EXPECT_EQ(ErrorOf(Replace(ExampleText(), "  kind: gige", "  kind: usb")),
            "rig.yaml:" + std::to_string(line) + ": camera.kind = 'usb': must be gige or v4l2");
}

// Refusals name the file, the line, the field, the value and the constraint.
TEST(RigFileTest, RefusalsNameFieldValueAndLimit) {
  const std::string t = ExampleText();
  EXPECT_EQ(ErrorOf(Replace(t, "fx: 2000", "fx: .nan")),
            "rig.yaml:" + std::to_string(LineOf(t, "fx: 2000")) +
                ": camera.fx = .nan: must be a finite number");
  EXPECT_EQ(ErrorOf(Replace(t, "  poses: 7", "  poses: 70")),
            "rig.yaml:" + std::to_string(LineOf(t, "  poses: 7")) +
                ": sliding_plate.poses = 70: must be in [2, 50]");
  EXPECT_EQ(ErrorOf(Replace(t, "exposure_us: 220000", "exposure_us: 260000")),
            "rig.yaml:" + std::to_string(LineOf(t, "exposure_us: 220000")) +
                ": camera.exposure_us = 260000: must be <= the frame period 1e6 / frame_rate_hz "
                "= 250000 us");
  // Shorter than the pattern period (0.2 s): a frame would miss triggers of its pattern.
  EXPECT_EQ(ErrorOf(Replace(t, "exposure_us: 220000", "exposure_us: 20000")),
            "rig.yaml:" + std::to_string(LineOf(t, "exposure_us: 220000")) +
                ": camera.exposure_us = 20000: must be >= the drives' pattern period "
                "(generators.signals.drive: 1 / gcd of the fast and slow frequencies) = 200000 "
                "us, so that a frame collects every trigger of its pattern (lower "
                "camera.frame_rate_hz to at most 1e6 / exposure_us)");
  EXPECT_EQ(ErrorOf(Replace(t, "validate: [3]", "validate: [4]")),
            "rig.yaml:" + std::to_string(LineOf(t, "validate: [3]")) +
                ": beams.validate[0] = 4: must be in [1, 3]");
  EXPECT_EQ(ErrorOf(Replace(t, "validate: [3]", "validate: [2, 3]")),
            "rig.yaml:" + std::to_string(LineOf(t, "validate: [3]")) +
                ": beams.validate: leaves 1 beam(s) to estimate from; the solver needs at least 2");
  EXPECT_EQ(ErrorOf(Replace(t, "world: {cols: 23", "world: {cols: 24")),
            "rig.yaml:" + std::to_string(LineOf(t, "world: {cols: 23")) +
                ": boards.world.cols = 24: must be odd (unique origin corner)");
  EXPECT_EQ(ErrorOf(Replace(t, "frame_min_separation: 0.5", "frame_min_separation: 0.1")),
            "rig.yaml:" + std::to_string(LineOf(t, "frame_min_separation: 0.5")) +
                ": step2.frame_min_separation = 0.1: must be in [0.15, 2.8284271247461903]");
  EXPECT_EQ(ErrorOf(Replace(t, "  identification_frames: true", "  identification_frames: 2")),
            "rig.yaml:" + std::to_string(LineOf(t, "  identification_frames: true")) +
                ": step1.identification_frames: must be true or false, got '2'");
  EXPECT_EQ(ErrorOf(Replace(t, "step2:\n", "step3:\n")),
            "rig.yaml:" + std::to_string(LineOf(t, "step2:\n")) +
                ": step3: unknown section (a rig file has generators, camera, hall_mcu, boards, "
                "beams, sliding_plate, step1, step2)");
  EXPECT_EQ(ErrorOf(Replace(t, "  dot_margin_squares: 1 ", "  dot_margin_squares: 101 ")),
            "rig.yaml:" + std::to_string(LineOf(t, "  dot_margin_squares: 1 ")) +
                ": sliding_plate.dot_margin_squares = 101: must be in [0, 100]");
  EXPECT_DOUBLE_EQ(
      ParseRigFile(Replace(t, "  dot_margin_squares: 1 ", "  dot_margin_squares: 6.5 "), "rig.yaml")
          .sliding_plate.dot_margin_squares,
      6.5);
  {
    // Both keys are optional; the gate's default margin is then 1 square.
    const RigFile r = ParseRigFile(
        std::regex_replace(t, std::regex("\n  dot_margin_squares: 1 [^\n]*"), ""), "rig.yaml");
    EXPECT_DOUBLE_EQ(r.sliding_plate.dot_margin_squares, 1);
    EXPECT_DOUBLE_EQ(r.step2.dot_margin_squares, 1);
  }
  EXPECT_EQ(ErrorOf(Replace(t, "  tilt_deg: 12", "  tilt: 12")),
            "rig.yaml:" + std::to_string(LineOf(t, "  tilt_deg: 12")) +
                ": sliding_plate.tilt: unknown key");
}

// The generator section's own validation (the mirror's limits) is part of loading the rig file,
// and points at the line of the field it names.
TEST(RigFileTest, ADriveOutsideTheChannelWindowIsRefusedAtLoad) {
  const std::string t = ExampleText();
  const std::string e = ErrorOf(Replace(t, "frequency_hz: 205,", "frequency_hz: 250,"));
  EXPECT_EQ(e, "rig.yaml:" + std::to_string(LineOf(t, "1: {role: fast_coil")) +
                   ": generators.unit1.ch1 (fast_coil): frequency_hz = 250 outside the window "
                   "[195, 215] Hz");
  // The sections' own loaders keep their messages (file, line, field).
  EXPECT_NE(ErrorOf(Replace(t, "rate_hz: 1000", "rate_hz: 9000")).find("hall_mcu.rate_hz"),
            std::string::npos);
}

// Every key of the example, replaced by a key that is not a name ("[x, y]: ..."), is refused
// with a message naming the file and a line, never yaml-cpp's bare "bad conversion" (found by
// the rig_yaml fuzzer).
TEST(RigFileTest, AKeyThatIsNotANameIsRefusedWithFileAndLineAnywhere) {
  const std::string t = ExampleText();
  const std::regex key_line(R"(^(\s*)([A-Za-z_][A-Za-z_0-9]*):)");
  std::istringstream lines(t);
  std::string line;
  int n = 0;
  int tried = 0;
  size_t offset = 0;
  while (std::getline(lines, line)) {
    ++n;
    std::smatch m;
    if (std::regex_search(line, m, key_line)) {
      std::string changed = t;
      changed.replace(offset + m[1].length(), m[2].length(), "[x, y]");
      const std::string e = ErrorOf(changed);
      EXPECT_EQ(e.rfind("rig.yaml:", 0), 0u) << "line " << n << ": " << e;
      EXPECT_EQ(e.find("bad conversion"), std::string::npos) << "line " << n << ": " << e;
      ++tried;
    }
    offset += line.size() + 1;
  }
  EXPECT_GT(tried, 40);
}

}  // namespace
}  // namespace msmcal::rig
