// A simulated interchange folder: written as `msmcal simulate` writes it, it reads back, passes
// ../shared/tools/validate-interchange, and the CLI is byte-for-byte deterministic per seed.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "mocks/rig/rig_simulator.h"
#include "mocks/rig/truth_io.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::sim {
namespace {

namespace fs = std::filesystem;
// The source / binary folders: from the test environment, else as configured at build time.
std::string EnvOr(const char* name, const char* fallback) {
  const char* v = std::getenv(name);
  return v && *v ? v : fallback;
}

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

fs::path TempDir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("msmcal_simfolder_test_" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir.parent_path());
  return dir;
}

// Removes this process's temporary folders at exit.
class TempCleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(
        fs::temp_directory_path() / ("msmcal_simfolder_test_" + std::to_string(::getpid())), ec);
  }
};
const auto* const kTempCleanup = ::testing::AddGlobalTestEnvironment(new TempCleanup);

// The msmcal binary of this build (the CLI tests skip when it is not built).
fs::path MsmcalBinary() {
  return fs::path(EnvOr("MSMCAL_BINARY_DIR", MSMCAL_TEST_BINARY_DIR)) / "app" / "msmcal";
}

// Small and quick: quarter-resolution camera, short Hall recordings.
constexpr const char* kSmallConfig = R"(seed: 11
camera: {width: 612, height: 512, fx: 500, fy: 500, cx: 305.75, cy: 255.75}
triggers: {min_separation_px: 10, max_triggers: 24}
hall: {background_duration_s: 1.0, actual_duration_s: 1.5}
render: {dot_sigma_mm: 1.5}
)";

bool HavePythonYaml() {
  return fs::exists("/usr/bin/python3") &&
         std::system("/usr/bin/python3 -c 'import yaml' >/dev/null 2>&1") == 0;
}

fs::path Validator() {
  return fs::path(EnvOr("MSMCAL_SOURCE_DIR", MSMCAL_TEST_SOURCE_DIR)) / ".." / "shared" / "tools" /
         "validate-interchange";
}

TEST(SimulateFolderTest, WritesReadsBackAndValidates) {
  const SimOptions options = ParseSimOptions(kSmallConfig, "small.yaml");
  const RigSimulator sim(options);
  EXPECT_TRUE(sim.warnings().empty()) << sim.warnings().front();
  const fs::path dir = TempDir("folder");
  const dataset::Recording rec = sim.MakeRecording(/*with_hall=*/true);
  for (size_t i = 0; i < rec.step1.size(); ++i)
    interchange::WriteImageAtomically(dir / rec.step1[i].file, sim.RenderStep1Frame(i));
  for (size_t i = 0; i < rec.step2.size(); ++i)
    interchange::WriteImageAtomically(dir / rec.step2[i].file, sim.RenderStep2Frame(i));
  WriteTruth(dir, MakeTruth(sim));
  interchange::WriteRecording(dir, rec);

  const dataset::Recording back = interchange::ReadRecording(dir);
  ASSERT_EQ(back.triggers.size(), rec.triggers.size());
  for (size_t j = 0; j < rec.triggers.size(); ++j)
    EXPECT_EQ(back.triggers[j].t_s, rec.triggers[j].t_s);
  EXPECT_EQ(back.step1.size(), rec.step1.size());
  EXPECT_EQ(back.step2.size(), rec.step2.size());
  ASSERT_TRUE(back.hall_actual.has_value());
  EXPECT_EQ(back.hall_actual->readings.size(), 1500u);
  EXPECT_EQ(back.hall_actual->clock_edges_us, rec.hall_actual->clock_edges_us);
  EXPECT_EQ(back.hall_background->readings.back().bz_uT,
            rec.hall_background->readings.back().bz_uT);
  EXPECT_EQ(back.camera.fx, 500.0);
  EXPECT_EQ(back.beams.back().role, dataset::BeamRole::kValidate);

  const fs::path validator = Validator();
  if (validator.empty() || !fs::exists(validator) || !HavePythonYaml()) {
    GTEST_SKIP() << "validate-interchange or python3-yaml not available";
  }
  const std::string cmd =
      "/usr/bin/python3 " + validator.string() + " " + dir.string() + " >/dev/null";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
}

TEST(SimulateFolderTest, CliIsDeterministicPerSeed) {
  const fs::path msmcal = MsmcalBinary();
  if (!fs::exists(msmcal)) GTEST_SKIP() << "msmcal binary not built";
  const fs::path cfg = TempDir("small.yaml");
  std::ofstream(cfg) << kSmallConfig;
  const fs::path a = TempDir("cli_a"), b = TempDir("cli_b"), c = TempDir("cli_c");
  auto run = [&](const fs::path& out, int seed) {
    const std::string cmd = msmcal.string() + " simulate " + out.string() + " --config " +
                            cfg.string() + " --seed " + std::to_string(seed) +
                            " --jobs 2 >/dev/null";
    return std::system(cmd.c_str());
  };
  ASSERT_EQ(run(a, 3), 0);
  ASSERT_EQ(run(b, 3), 0);
  ASSERT_EQ(run(c, 4), 0);
  int files = 0;
  for (const auto& e : fs::recursive_directory_iterator(a)) {
    if (!e.is_regular_file()) continue;
    const fs::path rel = fs::relative(e.path(), a);
    EXPECT_EQ(Slurp(e.path()), Slurp(b / rel)) << rel;
    ++files;
  }
  EXPECT_GT(files, 20);
  EXPECT_NE(Slurp(a / "hall" / "actual.csv"), Slurp(c / "hall" / "actual.csv"));
  EXPECT_NE(Slurp(a / "step2" / "0000.png"), Slurp(c / "step2" / "0000.png"));
  // Same geometry: the dots' truth does not depend on the seed.
  EXPECT_EQ(Slurp(a / "truth" / "dots.csv"), Slurp(c / "truth" / "dots.csv"));
  // A non-empty folder is refused without --overwrite.
  EXPECT_NE(run(a, 3), 0);
}

// --overwrite replaces a folder `msmcal simulate` wrote (truth/, no journal) and drops what was
// computed from the old data; a recorded session's folder (session.db) or any folder without
// truth/ is refused and left as it was.
TEST(SimulateFolderTest, OverwriteReplacesOnlyASimulatedFolder) {
  const fs::path msmcal = MsmcalBinary();
  if (!fs::exists(msmcal)) GTEST_SKIP() << "msmcal binary not built";
  const fs::path cfg = TempDir("small_ow.yaml");
  std::ofstream(cfg) << kSmallConfig;
  auto run = [&](const fs::path& out, bool overwrite) {
    const std::string cmd = msmcal.string() + " simulate " + out.string() + " --config " +
                            cfg.string() + " --no-images" + (overwrite ? " --overwrite" : "") +
                            " >/dev/null 2>&1";
    return std::system(cmd.c_str());
  };
  const fs::path sim = TempDir("ow_sim");
  ASSERT_EQ(run(sim, false), 0);
  fs::create_directories(sim / "results");
  std::ofstream(sim / "results" / "summary.json") << "{}";
  std::ofstream(sim / "report.html") << "old";
  std::ofstream(sim / "notes.txt") << "mine";
  ASSERT_EQ(run(sim, true), 0);
  EXPECT_TRUE(fs::exists(sim / "truth" / "mirror_planes.csv"));
  EXPECT_TRUE(fs::exists(sim / "session.yaml"));
  EXPECT_FALSE(fs::exists(sim / "results"));
  EXPECT_FALSE(fs::exists(sim / "report.html"));
  EXPECT_EQ(Slurp(sim / "notes.txt"), "mine");  // not one of its entries: kept

  const fs::path recorded = TempDir("ow_recorded");  // a session's folder: journal, images
  fs::create_directories(recorded / "step1");
  fs::create_directories(recorded / "truth");
  std::ofstream(recorded / "session.db") << "journal";
  std::ofstream(recorded / "session.yaml") << "recorded";
  std::ofstream(recorded / "step1" / "0000.png") << "frame";
  EXPECT_NE(run(recorded, true), 0);
  EXPECT_EQ(Slurp(recorded / "session.yaml"), "recorded");
  EXPECT_EQ(Slurp(recorded / "step1" / "0000.png"), "frame");
  EXPECT_EQ(Slurp(recorded / "session.db"), "journal");

  const fs::path other = TempDir("ow_other");  // no truth/: not the simulator's
  fs::create_directories(other / "hall");
  std::ofstream(other / "hall" / "actual.csv") << "readings";
  EXPECT_NE(run(other, true), 0);
  EXPECT_EQ(Slurp(other / "hall" / "actual.csv"), "readings");
}

}  // namespace
}  // namespace msmcal::sim
