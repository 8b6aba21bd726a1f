// The replay comparison: identical folders compare identical; a changed byte, pixel or JSON value
// is reported with its file; summary.json's timing keys and PNG encoding differences are not.
#include "sessions/replay/session_compare.h"

#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

namespace msmcal::replay {
namespace {

namespace fs = std::filesystem;

void Write(const fs::path& file, const std::string& text) {
  fs::create_directories(file.parent_path());
  std::ofstream(file, std::ios::binary) << text;
}

cv::Mat TestImage() {
  cv::Mat m(24, 32, CV_8UC1);
  for (int r = 0; r < m.rows; ++r)
    for (int c = 0; c < m.cols; ++c) m.at<uint8_t>(r, c) = static_cast<uint8_t>(r * 7 + c * 3);
  return m;
}

const char* kSummary = R"({
  "hall": {"delta_t_s": 0.00012},
  "mirror_poses": {"solve_time_s": 1.25, "ceres_time_s": 0.5, "ceres_iterations": 12,
                   "validation_rms_deg": 0.0031}
})";

// A small but complete session folder (every group of the comparison has a file).
void MakeSession(const fs::path& dir) {
  fs::remove_all(dir);
  Write(dir / "generators_transcript.txt", "unit1 > *IDN?\nunit1 < Agilent,33520B\n");
  Write(dir / "session.yaml", "format: msmcal-interchange/1\n");
  Write(dir / "camera.yaml", "image_size: [32, 24]\n");
  fs::create_directories(dir / "step1");
  fs::create_directories(dir / "rejected");
  cv::imwrite((dir / "step1" / "0000.png").string(), TestImage());
  cv::imwrite((dir / "rejected" / "step2_0001.png").string(), TestImage());
  Write(dir / "hall" / "actual.csv", "mcu_time_us,bx_uT,by_uT,bz_uT\n0,1,2,3\n1000,1,2,4\n");
  Write(dir / "hall" / "actual_clock.csv", "mcu_time_us\n500\n");
  Write(dir / "results" / "beams.csv", "beam,px,py,pz,vx,vy,vz\n1,0,0,0,0,0,1\n2,1,0,0,0,0,1\n");
  Write(dir / "results" / "summary.json", kSummary);
  Write(dir / "session_log.txt", "[   0.001 s] whatever the timing\n");  // never compared
}

struct Folders {
  fs::path a, b;
};

Folders Fresh(const std::string& name) {
  const fs::path root = fs::path(::testing::TempDir()) / ("replay_compare_" + name);
  Folders f{root / "a", root / "b"};
  MakeSession(f.a);
  MakeSession(f.b);
  Write(f.b / "session_log.txt", "[   0.002 s] other timing\n");
  // A recording cut short before a resume exists in the original only: not compared.
  Write(f.a / "hall" / "actual.partial-1.csv", "mcu_time_us,bx_uT,by_uT,bz_uT\n0,1,2,3\n");
  return f;
}

const FileComparison* Find(const SessionComparison& c, const std::string& file) {
  for (const auto& f : c.files)
    if (f.file == file) return &f;
  return nullptr;
}

TEST(SessionCompare, IdenticalFoldersCompareIdenticalInEveryGroup) {
  const Folders f = Fresh("identical");
  const SessionComparison c = CompareSessions(f.a, f.b);
  EXPECT_TRUE(c.identical()) << c.Table();
  EXPECT_TRUE(c.original_has_results);
  for (const char* file : {"generators_transcript.txt", "session.yaml", "camera.yaml",
                           "step1/0000.png", "rejected/step2_0001.png", "hall/actual.csv",
                           "hall/actual_clock.csv", "results/beams.csv", "results/summary.json"}) {
    const FileComparison* fc = Find(c, file);
    ASSERT_NE(fc, nullptr) << file;
    EXPECT_EQ(fc->verdict, Verdict::kSame) << file << ": " << fc->detail;
  }
  EXPECT_EQ(Find(c, "session_log.txt"), nullptr);
  EXPECT_EQ(c.files.size(), 9u);
  EXPECT_NE(c.Table().find("results           2      2        0        0  identical"),
            std::string::npos)
      << c.Table();
}

TEST(SessionCompare, AChangedByteInResultsIsReportedWithTheFileAndLine) {
  const Folders f = Fresh("byte");
  Write(f.b / "results" / "beams.csv", "beam,px,py,pz,vx,vy,vz\n1,0,0,0,0,0,1\n2,1,0,0,0,0,2\n");
  const SessionComparison c = CompareSessions(f.a, f.b);
  EXPECT_FALSE(c.identical());
  const auto d = c.Differences();
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].file, "results/beams.csv");
  EXPECT_EQ(d[0].group, "results");
  EXPECT_EQ(d[0].verdict, Verdict::kDiffers);
  EXPECT_NE(d[0].detail.find("line 3"), std::string::npos) << d[0].detail;
  EXPECT_NE(c.Table().find("DIFFERENT"), std::string::npos);
}

TEST(SessionCompare, SummaryTimingKeysAreIgnoredOtherKeysAreNot) {
  const Folders f = Fresh("summary");
  // Other timings, other key order and layout: still the same.
  Write(f.b / "results" / "summary.json",
        R"({"mirror_poses": {"validation_rms_deg": 0.0031, "ceres_iterations": 12,
            "ceres_time_s": 9.5, "solve_time_s": 30.0}, "hall": {"delta_t_s": 0.00012}})");
  EXPECT_TRUE(CompareSessions(f.a, f.b).identical());

  Write(f.b / "results" / "summary.json",
        R"({"mirror_poses": {"validation_rms_deg": 0.0032, "ceres_iterations": 12,
            "ceres_time_s": 0.5, "solve_time_s": 1.25}, "hall": {"delta_t_s": 0.00012}})");
  const auto d = CompareSessions(f.a, f.b).Differences();
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].file, "results/summary.json");
  EXPECT_NE(d[0].detail.find("/mirror_poses/validation_rms_deg"), std::string::npos) << d[0].detail;

  // A timing key present in one only is ignored too.
  Write(f.b / "results" / "summary.json",
        R"({"mirror_poses": {"validation_rms_deg": 0.0031, "ceres_iterations": 12},
            "hall": {"delta_t_s": 0.00012}})");
  EXPECT_TRUE(CompareSessions(f.a, f.b).identical());
  EXPECT_EQ(SummaryJsonWithoutTiming(kSummary, "a"),
            SummaryJsonWithoutTiming(
                R"({"hall":{"delta_t_s":0.00012},"mirror_poses":{"ceres_iterations":12,
                    "validation_rms_deg":0.0031}})",
                "b"));
  EXPECT_THROW(SummaryJsonWithoutTiming("{not json", "x.json"), std::runtime_error);

  // The report's provenance (command line, host, times) describes the run, not its results.
  Write(f.b / "results" / "summary.json",
        R"({"mirror_poses": {"validation_rms_deg": 0.0031, "ceres_iterations": 12},
            "hall": {"delta_t_s": 0.00012},
            "provenance": {"command_line": "msmcal replay x", "host": "h"}})");
  EXPECT_TRUE(CompareSessions(f.a, f.b).identical());
}

TEST(SessionCompare, ImagesAreComparedByPixelsNotByEncoding) {
  const Folders f = Fresh("pixels");
  // Same pixels, another PNG compression level: different bytes, same image.
  cv::imwrite((f.b / "step1" / "0000.png").string(), TestImage(), {cv::IMWRITE_PNG_COMPRESSION, 0});
  EXPECT_TRUE(CompareSessions(f.a, f.b).identical());

  cv::Mat changed = TestImage();
  changed.at<uint8_t>(5, 6) ^= 1;
  cv::imwrite((f.b / "rejected" / "step2_0001.png").string(), changed);
  const auto d = CompareSessions(f.a, f.b).Differences();
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].file, "rejected/step2_0001.png");
  EXPECT_EQ(d[0].detail, "1 pixel values differ");
}

TEST(SessionCompare, MissingFilesAreDifferencesOnEitherSide) {
  const Folders f = Fresh("missing");
  fs::remove(f.b / "hall" / "actual_clock.csv");
  Write(f.b / "results" / "extra.csv", "x\n");
  const SessionComparison c = CompareSessions(f.a, f.b);
  const auto d = c.Differences();
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(Find(c, "hall/actual_clock.csv")->verdict, Verdict::kMissingInReplay);
  EXPECT_EQ(Find(c, "results/extra.csv")->verdict, Verdict::kMissingInOriginal);
}

TEST(SessionCompare, WithoutResultsInTheOriginalOnlyTheAcquisitionIsCompared) {
  const Folders f = Fresh("no_results");
  fs::remove_all(f.a / "results");
  const SessionComparison c = CompareSessions(f.a, f.b);
  EXPECT_FALSE(c.original_has_results);
  EXPECT_TRUE(c.identical()) << c.Table();
  EXPECT_EQ(Find(c, "results/beams.csv"), nullptr);
  EXPECT_NE(c.Table().find("not compared (the original has no results/)"), std::string::npos);
  EXPECT_THROW(CompareSessions(f.a / "nope", f.b), std::runtime_error);
}

}  // namespace
}  // namespace msmcal::replay
