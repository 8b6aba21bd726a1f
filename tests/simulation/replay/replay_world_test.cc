// ReplayWorld (recorded images as the rig's current setup, frame freshness) and the replay's
// configuration helpers, without instruments.
#include "simulation/replay/replay_world.h"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cstdlib>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "simulation/replay/replay_config.h"

namespace msmcal::replay {
namespace {

namespace fs = std::filesystem;

cv::Mat Image(uint8_t base) {
  cv::Mat m(6, 8, CV_8UC1);
  for (int r = 0; r < m.rows; ++r)
    for (int c = 0; c < m.cols; ++c) m.at<uint8_t>(r, c) = static_cast<uint8_t>(base + r * 8 + c);
  return m;
}

// A folder as the orchestrator leaves it: step1/0000.png accepted, step2/0000.png accepted,
// step2/0001.png rejected (kept as rejected/step2_0001.png).
struct Folder {
  fs::path dir;
  dataset::Recording plan;
};

Folder MakeFolder(const std::string& name) {
  Folder f;
  f.dir = fs::path(::testing::TempDir()) / ("replay_world_" + name);
  fs::remove_all(f.dir);
  fs::create_directories(f.dir / "step1");
  fs::create_directories(f.dir / "step2");
  fs::create_directories(f.dir / "rejected");
  cv::imwrite((f.dir / "step1" / "0000.png").string(), Image(10));
  cv::imwrite((f.dir / "step2" / "0000.png").string(), Image(100));
  cv::imwrite((f.dir / "rejected" / "step2_0001.png").string(), Image(200));
  f.plan.step1 = {{"step1/0000.png", 0, {1}}};
  f.plan.step2 = {{"step2/0000.png", dataset::Step2Kind::kNeutral, {}, {1}},
                  {"step2/0001.png", dataset::Step2Kind::kScan, {0}, {1}}};
  return f;
}

// Fills one frame of width x height through the source, as the camera thread does.
std::vector<uint8_t> Fill(sim::FrameSource& source, int width, int height, int64_t timestamp_ns) {
  std::vector<uint8_t> frame(static_cast<size_t>(width * height), 0xAB);
  source(frame.data(), width, height, sim::SimPixelFormat::kMono8, timestamp_ns, 0);
  return frame;
}

camera::FrameInfo Info(int64_t timestamp_ns) {
  camera::FrameInfo i;
  i.device_timestamp_ns = timestamp_ns;
  return i;
}

TEST(RecordedImagePath, PrefersTheAcceptedImageThenTheKeptReject) {
  const Folder f = MakeFolder("paths");
  EXPECT_EQ(RecordedImagePath(f.dir, "step1/0000.png"), f.dir / "step1" / "0000.png");
  EXPECT_EQ(RecordedImagePath(f.dir, "step2/0001.png"), f.dir / "rejected" / "step2_0001.png");
  EXPECT_TRUE(RecordedImagePath(f.dir, "step2/0002.png").empty());
}

TEST(ReplayWorld, ServesTheRecordedImageOfTheCurrentSetupAndTellsFreshFrames) {
  const Folder f = MakeFolder("serve");
  std::vector<orchestrator::HallRun> asked;
  ReplayWorld world(f.dir, f.plan, [&](orchestrator::HallRun run) {
    asked.push_back(run);
    return std::string("/dev/pts/test");
  });
  sim::FrameSource source = world.MakeFrameSource();
  const int w = 10, h = 7;  // larger than the images: placed top-left, the rest black

  const std::vector<uint8_t> before = Fill(source, w, h, 1000);
  for (uint8_t b : before) ASSERT_EQ(b, 0);  // black before the first setup

  world.PrepareStep1Frame(0);
  EXPECT_FALSE(world.FrameShowsCurrentSetup(Info(1000)));  // filled before the change
  const std::vector<uint8_t> s1 = Fill(source, w, h, 2000);
  EXPECT_TRUE(world.FrameShowsCurrentSetup(Info(2000)));
  EXPECT_FALSE(world.FrameShowsCurrentSetup(Info(9999)));  // never filled
  const cv::Mat expected = Image(10);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c)
      ASSERT_EQ(s1[static_cast<size_t>(r * w + c)],
                r < expected.rows && c < expected.cols ? expected.at<uint8_t>(r, c) : 0)
          << r << "," << c;

  world.PrepareStep2Frame(1);  // rejected by the original run: its kept image is served
  EXPECT_FALSE(world.FrameShowsCurrentSetup(Info(2000)));
  const std::vector<uint8_t> s2 = Fill(source, w, h, 3000);
  EXPECT_TRUE(world.FrameShowsCurrentSetup(Info(3000)));
  EXPECT_EQ(s2[0], Image(200).at<uint8_t>(0, 0));
  EXPECT_EQ(world.generation(), 2u);

  EXPECT_THROW(world.PrepareStep2Frame(2), std::out_of_range);
  EXPECT_EQ(world.PrepareHallRecording(orchestrator::HallRun::kActual), "/dev/pts/test");
  ASSERT_EQ(asked.size(), 1u);
  EXPECT_EQ(asked[0], orchestrator::HallRun::kActual);
}

TEST(ReplayWorld, AMissingImageIsNamedBeforeAnythingStarts) {
  Folder f = MakeFolder("missing");
  fs::remove(f.dir / "step2" / "0000.png");
  try {
    ReplayWorld world(f.dir, f.plan, [](orchestrator::HallRun) { return std::string(); });
    FAIL() << "no error for the missing image";
  } catch (const std::runtime_error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find((f.dir / "step2" / "0000.png").string()), std::string::npos) << m;
    EXPECT_NE(m.find("rejected/step2_0000.png"), std::string::npos) << m;
  }
}

TEST(ReplayConfig, ReplayRunConfigRoundTripsTheSourceRun) {
  SourceRun run{"demo", "seed: 3\nstep1:\n  poses: 4\n"};
  const std::string yaml = ReplayRunConfigYaml("/data/sessions/A", run);
  fs::path source;
  const SourceRun back = ParseReplayRunConfigYaml(yaml, "test", &source);
  EXPECT_EQ(back.kind, "demo");
  EXPECT_EQ(back.config_yaml, run.config_yaml);
  EXPECT_EQ(source, fs::path("/data/sessions/A"));
  EXPECT_THROW(ParseReplayRunConfigYaml("replay_of: /x\n", "meta", nullptr), std::runtime_error);
  try {
    ParseReplayRunConfigYaml("replay_of: /x\nsource_run_kind: demo\n", "meta", nullptr);
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("source_run_config_yaml"), std::string::npos);
  }
}

TEST(ReplayConfig, DemoSetupFollowsTheSimulatorOptions) {
  sim::SimOptions o;
  o.seed = 3;
  o.hall.sample_rate_hz = 500;
  o.mirror.fast.amplitude_vpp = 1.5;
  const RigSetup s = SetupFromSourceRun({"demo", sim::SimOptionsToYaml(o)});
  EXPECT_EQ(s.mcu_rate_hz, 500);
  EXPECT_EQ(s.mcu.stall_timeout_ms, 2000);
  EXPECT_DOUBLE_EQ(s.generators.signals.fast.amplitude_vpp, 1.5);
  EXPECT_DOUBLE_EQ(s.generators.signals.fast.frequency_hz, o.mirror.fast.frequency_hz);
  EXPECT_DOUBLE_EQ(s.generators.signals.slow.frequency_hz, o.mirror.slow.frequency_hz);
  // Limits come from the demo rig file, never from the request (issue 17): a drive far beyond
  // them is refused, not accommodated.
  EXPECT_DOUBLE_EQ(s.generators.unit1.limits[0].max_vpp, 4.0);
  auto validated = [](gen::RigGeneratorConfig g) {  // on some ports (a replay has none)
    g.unit1.link.port = g.unit2.link.port = 5025;
    return g.Validate();
  };
  EXPECT_EQ(validated(s.generators), "");
  o.mirror.fast.amplitude_vpp = 1000;
  const RigSetup big = SetupFromSourceRun({"demo", sim::SimOptionsToYaml(o)});
  EXPECT_DOUBLE_EQ(big.generators.unit1.limits[0].max_vpp, 4.0);
  EXPECT_EQ(validated(big.generators),
            "generators.generator1.ch1 (fast_coil): amplitude_vpp = 1000 outside the limit [0, 4] "
            "Vpp");
  EXPECT_THROW(SetupFromSourceRun({"guided", ""}), std::runtime_error);
}

TEST(ReplayConfig, LabSetupComesFromTheJournalledRigConfiguration) {
  const char* src = std::getenv("MSMCAL_SOURCE_DIR");
  const fs::path rig_file = fs::path(src ? src : MSMCAL_TEST_SOURCE_DIR) / "config" / "rig.yaml";
  std::ifstream in(rig_file);
  ASSERT_TRUE(in) << rig_file;
  std::stringstream rig;
  rig << in.rdbuf();
  // As `msmcal session run` journals it (app/session_flow.cc).
  YAML::Emitter e;
  e << YAML::BeginMap << YAML::Key << "rig_file" << YAML::Value << rig_file.string() << YAML::Key
    << "camera_address" << YAML::Value << "192.168.1.20" << YAML::Key << "rig_yaml" << YAML::Value
    << YAML::Literal << rig.str() << YAML::EndMap;
  const RigSetup s = SetupFromSourceRun({"lab", e.c_str()});
  const gen::RigGeneratorConfig want = gen::ParseRigGeneratorConfig(rig.str(), "rig.yaml");
  EXPECT_EQ(s.generators.signals.fast.frequency_hz, want.signals.fast.frequency_hz);
  EXPECT_EQ(s.generators.signals.slow.amplitude_vpp, want.signals.slow.amplitude_vpp);
  EXPECT_EQ(s.generators.unit1.limits[0].max_vpp, want.unit1.limits[0].max_vpp);
  EXPECT_EQ(s.mcu_rate_hz, 1000);
  EXPECT_EQ(s.mcu.stall_timeout_ms, 500);
  EXPECT_EQ(s.mcu_sensor.gain_sel, 7);
  // A bare rig configuration is accepted as well.
  EXPECT_EQ(SetupFromSourceRun({"lab", rig.str()}).generators.signals.fast.frequency_hz,
            want.signals.fast.frequency_hz);
}

TEST(ReplayConfig, RecordedIdentitiesComeFromTheTranscript) {
  const std::string t =
      "unit1 > *IDN?\nunit1 < Keysight Technologies,33522B,MY5900123,5.03\n"
      "unit2 > *IDN?\nunit2 < Agilent Technologies,33522B,MY5200777,3.05\n"
      "unit2 > *OPT?\nunit2 < MEM\nunit1 > *RST;*CLS\nunit1 > *IDN?\nunit1 < later\n";
  EXPECT_EQ(IdentityFromTranscript(t, "unit1").identity,
            "Keysight Technologies,33522B,MY5900123,5.03");
  EXPECT_EQ(IdentityFromTranscript(t, "unit1").options_reply, "");
  EXPECT_EQ(IdentityFromTranscript(t, "unit2").identity,
            "Agilent Technologies,33522B,MY5200777,3.05");
  EXPECT_EQ(IdentityFromTranscript(t, "unit2").options_reply, "MEM");
  EXPECT_EQ(IdentityFromTranscript("", "unit1").identity, "");
}

}  // namespace
}  // namespace msmcal::replay
