#include "sessions/store/transfer.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "sessions/interchange/interchange_io.h"
#include "sessions/store/catalogue.h"
#include "tests/testing/test_files.h"

namespace msmcal::store {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// Per-test folders named msmcal_xfer_<suite>_<test>_<pid>.
class TempDir : public msmcal::testing::TempDir {
 public:
  TempDir() : msmcal::testing::TempDir("msmcal_xfer") {}
};

using msmcal::testing::Slurp;
using msmcal::testing::Spit;

std::vector<std::string> FilesUnder(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) out.push_back(fs::relative(e.path(), dir).generic_string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// An interchange folder written by msmcal, with images, MARG, results and truth files.
dataset::Recording MakeFolder(const fs::path& dir) {
  dataset::Recording r;
  r.camera.width = 64;
  r.camera.height = 48;
  r.camera.fx = 80.125;
  r.camera.fy = 80.5;
  r.camera.cx = 31.5;
  r.camera.cy = 23.75;
  r.camera.distortion = {-0.1, 1e-7, 0, -0.0, 3};
  r.world_board = {9, 6, 10};
  r.sliding_board = {7, 4, 12.5};
  r.beams = {{1, dataset::BeamRole::kEstimate},
             {2, dataset::BeamRole::kEstimate},
             {3, dataset::BeamRole::kValidate}};
  r.drive.fast = {1234.5, 2.5, 0.1};
  r.drive.slow = {61.25, 1.5, -90};
  r.drive.pattern_period_s = 0.2;
  r.clock_frequency_hz = 5;
  for (int j = 0; j < 6; ++j) r.triggers.push_back({j, 0.2 * j / 6});
  cv::Mat mono(48, 64, CV_8UC1);
  cv::Mat bgr(48, 64, CV_16UC3);
  cv::randu(mono, 0, 256);
  cv::randu(bgr, 0, 65536);
  for (int i = 0; i < 4; ++i) {
    const std::string file = "step1/000" + std::to_string(i) + ".png";
    r.step1.push_back({file, i / 3, i < 3 ? std::vector<int>{i + 1} : std::vector<int>{1, 2, 3}});
    interchange::WriteImageAtomically(dir / file, mono);
  }
  r.step2.push_back({"step2/0000.png", dataset::Step2Kind::kNeutral, {}, {1, 2, 3}});
  r.step2.push_back({"step2/0001.png", dataset::Step2Kind::kFastOnly, {0, 3}, {1, 2, 3}});
  r.step2.push_back({"step2/0002.png", dataset::Step2Kind::kScan, {1, 2, 4}, {1, 2, 3}});
  for (const auto& f : r.step2) interchange::WriteImageAtomically(dir / f.file, bgr);
  dataset::HallRecording hall;
  for (int i = 0; i < 300; ++i) {
    hall.readings.push_back({1000.0 * i + 7, 0.1 * i, -1e-9 * i, i % 2 ? -0.0 : 1e300});
  }
  hall.clock_edges_us = {5, 200005, 400005};
  r.hall_actual = hall;
  hall.readings.resize(20);
  r.hall_background = hall;
  dataset::MargRecording marg;
  marg.has_inertial = false;
  marg.samples.push_back({0.5, 0, 0, 0, 0, 0, 0, 1, 2, 3});
  r.marg_validation = marg;
  interchange::WriteRecording(dir, r);
  Spit(dir / "results/beams.csv", "beam,px,py,pz,vx,vy,vz\n1,1,2,3,0,0,1\n");
  Spit(dir / "results/summary.json", "{\"validation\": {\"rms_px\": 0.375}}\n");
  Spit(dir / "truth/planes.csv", "j,nx\n0,1\n");
  return r;
}

TEST(TransferTest, ImportThenExportIsByteIdentical) {
  TempDir tmp;
  FakeClock clock(1'763'900'000'000'000'000);
  const fs::path src = tmp.path() / "src";
  MakeFolder(src);
  auto store = ImportInterchange(src, tmp.path() / "sessions/a", clock, {"rig-1", "msm-9", ""});
  EXPECT_EQ(store->IntegrityCheck(), "ok");
  EXPECT_EQ(store->Counts().frames, 7);
  EXPECT_EQ(store->Counts().hall_readings.at("actual"), 300);
  EXPECT_EQ(*store->GetMeta("rig_id"), "rig-1");
  EXPECT_EQ(*store->GetMeta("drive.fast.frequency_hz"), "1234.5");
  // No staging folder left beside the session.
  EXPECT_EQ(FilesUnder(tmp.path() / "sessions").size(),
            FilesUnder(tmp.path() / "sessions/a").size());

  const fs::path out = tmp.path() / "out";
  ExportInterchange(*store, out);
  const auto files = FilesUnder(src);
  EXPECT_EQ(files, FilesUnder(out));
  EXPECT_THAT(files, ::testing::Contains("truth/planes.csv"));
  EXPECT_THAT(files, ::testing::Contains("results/summary.json"));
  EXPECT_THAT(files, ::testing::Contains("marg/validation.csv"));
  for (const auto& f : files) EXPECT_EQ(Slurp(src / f), Slurp(out / f)) << f;
  // Images decode to the same pixels (follows from byte identity; checked for one anyway).
  const cv::Mat a = cv::imread((src / "step2/0002.png").string(), cv::IMREAD_UNCHANGED);
  const cv::Mat b = cv::imread((out / "step2/0002.png").string(), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);

  // A re-import of the export gives the same export again.
  auto again = ImportInterchange(out, tmp.path() / "sessions/b", clock);
  ExportInterchange(*again, tmp.path() / "out2");
  for (const auto& f : files) EXPECT_EQ(Slurp(src / f), Slurp(tmp.path() / "out2" / f)) << f;
}

TEST(TransferTest, HandWrittenFolderKeepsYamlVerbatimAndCsvValues) {
  TempDir tmp;
  FakeClock clock;
  const fs::path src = tmp.path() / "src";
  Spit(src / "camera.yaml",
       "# lab camera\nimage_size: [640, 480]\nK: [[500.5, 0, 320], [0, 501, 240.25], [0, 0, 1]]\n"
       "distortion: [0.1, -0.01, 0, 0, 1e-3]\n");
  Spit(src / "session.yaml", R"(format: msmcal-interchange/1   # ours
boards:
  world:   {inner_corners: [9, 6], square_mm: 10.0}
  sliding: {inner_corners: [7, 4], square_mm: 12.5}
beams:
  - {id: 1, role: estimate}
drive:
  fast: {frequency_hz: 1200, amplitude_vpp: 2.5, phase_deg: 0}
  slow: {frequency_hz: 60, amplitude_vpp: 1.0, phase_deg: 90}
  pattern_period_s: 0.05
clock: {frequency_hz: 20}
triggers:
  - {j: 0, t_s: 0.001}
step1:
  frames:
    - {file: step1/0000.png, pose: 0, beams: [1]}
step2:
  frames:
    - file: step2/0000.png
      kind: scan
      triggers: [0]
      beams: [1]
)");
  cv::Mat img(4, 4, CV_8UC1, cv::Scalar(9));
  interchange::WriteImageAtomically(src / "step1/0000.png", img);
  interchange::WriteImageAtomically(src / "step2/0000.png", img);
  Spit(src / "hall/actual.csv", "mcu_time_us,bx_uT,by_uT,bz_uT\r\n10,1.50,-2,3e2\r\n");
  Spit(src / "hall/actual_clock.csv", "mcu_time_us\n5\n");
  auto store = ImportInterchange(src, tmp.path() / "s", clock);
  ExportInterchange(*store, tmp.path() / "out");
  EXPECT_EQ(Slurp(src / "session.yaml"), Slurp(tmp.path() / "out/session.yaml"));
  EXPECT_EQ(Slurp(src / "camera.yaml"), Slurp(tmp.path() / "out/camera.yaml"));
  EXPECT_EQ(Slurp(tmp.path() / "out/hall/actual.csv"),
            "mcu_time_us,bx_uT,by_uT,bz_uT\n10,1.5,-2,300\n");
  const auto r1 = interchange::ReadRecording(src);
  const auto r2 = interchange::ReadRecording(tmp.path() / "out");
  EXPECT_EQ(r1.hall_actual->readings[0].bz_uT, r2.hall_actual->readings[0].bz_uT);
  EXPECT_EQ(r1.hall_actual->clock_edges_us, r2.hall_actual->clock_edges_us);
}

TEST(TransferTest, ChangedSessionExportsRegeneratedYaml) {
  TempDir tmp;
  FakeClock clock;
  const fs::path src = tmp.path() / "src";
  MakeFolder(src);
  auto store = ImportInterchange(src, tmp.path() / "s", clock);
  FrameRecord extra;
  extra.step = "step2";
  extra.file = "step2/0003.png";
  extra.kind = dataset::Step2Kind::kScan;
  extra.triggers = {5};
  extra.beams = {1};
  store->AddFrame(extra, cv::Mat(4, 4, CV_8UC1, cv::Scalar(1)));
  ExportInterchange(*store, tmp.path() / "out");
  const auto r = interchange::ReadRecording(tmp.path() / "out");
  ASSERT_EQ(r.step2.size(), 4u);
  EXPECT_EQ(r.step2[3].triggers, std::vector<int>{5});
}

TEST(TransferTest, InvalidFolderCreatesNothing) {
  TempDir tmp;
  FakeClock clock;
  const fs::path src = tmp.path() / "src";
  MakeFolder(src);
  fs::remove(src / "step2/0001.png");
  try {
    ImportInterchange(src, tmp.path() / "sessions/x", clock);
    ADD_FAILURE() << "import of an invalid folder succeeded";
  } catch (const interchange::InterchangeError& e) {
    EXPECT_THAT(e.what(), HasSubstr("referenced image 'step2/0001.png' not found"));
  }
  EXPECT_FALSE(fs::exists(tmp.path() / "sessions/x"));
  EXPECT_TRUE(!fs::exists(tmp.path() / "sessions") || fs::is_empty(tmp.path() / "sessions"));
}

TEST(TransferTest, ExportRefusesNonEmptyFolder) {
  TempDir tmp;
  FakeClock clock;
  MakeFolder(tmp.path() / "src");
  auto store = ImportInterchange(tmp.path() / "src", tmp.path() / "s", clock);
  try {
    ExportInterchange(*store, tmp.path() / "src");
    ADD_FAILURE() << "export into a non-empty folder succeeded";
  } catch (const StoreError& e) {
    EXPECT_THAT(e.what(), HasSubstr("exists and is not empty"));
  }
}

TEST(TransferTest, ResultsFromFolderAreExported) {
  TempDir tmp;
  FakeClock clock;
  MakeFolder(tmp.path() / "src");
  auto store = ImportInterchange(tmp.path() / "src", tmp.path() / "s", clock);
  Spit(tmp.path() / "solve/summary.json", "{\"rms\": 0.5}\n");
  Spit(tmp.path() / "solve/mirror_planes.csv", "j\n");
  PutResultsFromFolder(*store, tmp.path() / "solve");
  EXPECT_EQ(*ResultRms(*store), 0.5);
  store->PutResult("summary.json",
                   R"({"baseline_validation_rms_px": 9, "validation_rms_deg": 0.1, )"
                   R"("validation_rms_px": 0.75})");
  EXPECT_EQ(*ResultRms(*store), 0.75);
  store->PutResult("summary.json", R"({"baseline_validation_rms_px": 9, "x": {"fit_rms": 2}})");
  EXPECT_EQ(*ResultRms(*store), 2);
  store->PutResult("summary.json", "{\"rms\": 0.5}\n");
  ExportInterchange(*store, tmp.path() / "out");
  EXPECT_EQ(Slurp(tmp.path() / "out/results/summary.json"), "{\"rms\": 0.5}\n");
  EXPECT_EQ(Slurp(tmp.path() / "out/results/mirror_planes.csv"), "j\n");
  EXPECT_EQ(Slurp(tmp.path() / "out/results/beams.csv"),
            Slurp(tmp.path() / "src/results/beams.csv"));
}

TEST(CatalogueTest, ListsAndFilters) {
  TempDir tmp;
  const fs::path root = tmp.path() / "sessions";
  MakeFolder(tmp.path() / "src");
  FakeClock clock;
  clock.Set(*ParseUtc("2026-01-10"));
  ImportInterchange(tmp.path() / "src", root / "old", clock, {"rig-1", "msm-1", ""});
  clock.Set(*ParseUtc("2026-03-05T12:00:00Z"));
  ImportInterchange(tmp.path() / "src", root / "new", clock, {"rig-2", "msm-1", ""});
  fs::create_directories(root / "not-a-session");
  const auto all = ListSessions(root, {}, clock);
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].id, "old");
  EXPECT_EQ(all[1].id, "new");
  EXPECT_EQ(FormatUtc(all[1].created_ns), "2026-03-05T12:00:00Z");
  EXPECT_EQ(all[0].frames, 7);
  EXPECT_EQ(all[0].fast_frequency_hz, 1234.5);
  EXPECT_EQ(all[0].slow_amplitude_vpp, 1.5);
  ASSERT_TRUE(all[0].result_rms);
  EXPECT_EQ(*all[0].result_rms, 0.375);
  CatalogueFilter by_rig;
  by_rig.rig_id = "rig-2";
  ASSERT_EQ(ListSessions(root, by_rig, clock).size(), 1u);
  EXPECT_EQ(ListSessions(root, by_rig, clock)[0].id, "new");
  CatalogueFilter since;
  since.since_ns = ParseUtc("2026-02-01");
  ASSERT_EQ(ListSessions(root, since, clock).size(), 1u);
  CatalogueFilter mirror;
  mirror.mirror_id = "msm-1";
  EXPECT_EQ(ListSessions(root, mirror, clock).size(), 2u);
  EXPECT_EQ(ResolveSession("new", root), root / "new");
  EXPECT_THROW(ResolveSession("none", root), StoreError);
  EXPECT_FALSE(ParseUtc("2026-13-01"));
  EXPECT_FALSE(ParseUtc("yesterday"));
}

}  // namespace
}  // namespace msmcal::store
