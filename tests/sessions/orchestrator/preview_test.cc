// Annotated previews: what the gate found is drawn where it was found, the image is BGR and
// within the size limit, the input is left alone, and the preview file is written atomically.
#include "sessions/orchestrator/preview.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mocks/rig/rig_simulator.h"

namespace msmcal::orchestrator {
namespace {

namespace fs = std::filesystem;

// Number of pixels in the (2r+1)^2 window around `px` that differ between a and b (BGR).
int ChangedAround(const cv::Mat& a, const cv::Mat& b, const Eigen::Vector2d& px, int r) {
  int n = 0;
  for (int y = int(std::lround(px.y())) - r; y <= int(std::lround(px.y())) + r; ++y)
    for (int x = int(std::lround(px.x())) - r; x <= int(std::lround(px.x())) + r; ++x)
      if (x >= 0 && y >= 0 && x < a.cols && y < a.rows &&
          a.at<cv::Vec3b>(y, x) != b.at<cv::Vec3b>(y, x))
        ++n;
  return n;
}

// A 4 x 3 corner grid and two dots on a plain grey image.
struct Synthetic {
  cv::Mat image = cv::Mat(600, 800, CV_8UC1, cv::Scalar(100));
  GateResult gate;
  PreviewLabels labels;
  Synthetic() {
    vision::CheckerboardDetection board;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) board.corners_px.emplace_back(200 + 40 * c, 300 + 40 * r);
    gate.boards = {board};
    vision::Dot d0, d1;
    d0.px = {600.3, 150.7};
    d0.cov_px2 << 0.04, 0.01, 0.01, 0.02;
    d1.px = {650.0, 450.0};
    d1.cov_px2 << 4.0, 0.0, 0.0, 1.0;  // large: a visible 4 x 2 px ellipse
    gate.dots = {d0, d1};
    gate.accepted = true;
    gate.dots_found = 2;
    gate.dots_expected = 2;
    labels = MakePreviewLabels("step2/0004.png", 2, dataset::BoardSpec{4, 3, 10},
                               dataset::BoardSpec{13, 8, 10});
  }
};

TEST(Preview, DrawsCornersDotsAndBannerOnABgrCopy) {
  Synthetic s;
  const cv::Mat before = s.image.clone();
  const cv::Mat out = AnnotatePreview(s.image, s.gate, s.labels, /*max_width_px=*/0);
  EXPECT_EQ(out.type(), CV_8UC3);
  EXPECT_EQ(out.size(), s.image.size());
  EXPECT_EQ(cv::norm(before, s.image, cv::NORM_INF), 0.0);  // input untouched
  cv::Mat plain;
  cv::cvtColor(s.image, plain, cv::COLOR_GRAY2BGR);
  for (const auto& c : s.gate.boards[0]->corners_px)
    EXPECT_GT(ChangedAround(plain, out, c, 3), 0) << c.transpose();
  for (const auto& d : s.gate.dots) EXPECT_GT(ChangedAround(plain, out, d.px, 2), 0);
  // The 2-sigma ellipse of dot 1 (sigma 2 px along x) reaches 4 px from the centre.
  EXPECT_NE(out.at<cv::Vec3b>(450, 654), plain.at<cv::Vec3b>(450, 654));
  // Banner across the top; a region far from every drawing is untouched.
  EXPECT_EQ(out.at<cv::Vec3b>(5, 790), cv::Vec3b(32, 32, 32));
  EXPECT_EQ(out.at<cv::Vec3b>(580, 20), plain.at<cv::Vec3b>(580, 20));
}

TEST(Preview, DownscalesToTheWidthLimitAndDrawsAtTheScaledPositions) {
  Synthetic s;
  cv::Mat big;
  cv::resize(s.image, big, cv::Size(3200, 2400), 0, 0, cv::INTER_NEAREST);
  for (auto& c : s.gate.boards[0]->corners_px) c = (c.array() + 0.5) * 4.0 - 0.5;
  for (auto& d : s.gate.dots) d.px = (d.px.array() + 0.5) * 4.0 - 0.5;
  const cv::Mat out = AnnotatePreview(big, s.gate, s.labels, 800);
  EXPECT_EQ(out.cols, 800);
  EXPECT_EQ(out.rows, 600);
  cv::Mat plain(600, 800, CV_8UC3, cv::Scalar(100, 100, 100));
  for (const auto& d : s.gate.dots)
    EXPECT_GT(ChangedAround(plain, out, (d.px.array() + 0.5) / 4.0 - 0.5, 2), 0);
  // Smaller images are not enlarged.
  EXPECT_EQ(AnnotatePreview(s.image, s.gate, s.labels, 1600).size(), s.image.size());
}

TEST(Preview, AcceptsSixteenBitAndColourAndRejectsOtherTypes) {
  Synthetic s;
  cv::Mat sixteen(s.image.size(), CV_16UC1, cv::Scalar(100 * 257));
  const cv::Mat a = AnnotatePreview(sixteen, s.gate, s.labels, 0);
  EXPECT_EQ(a.type(), CV_8UC3);
  EXPECT_EQ(a.at<cv::Vec3b>(580, 20), cv::Vec3b(100, 100, 100));
  cv::Mat colour(s.image.size(), CV_8UC3, cv::Scalar(10, 20, 30));
  EXPECT_EQ(AnnotatePreview(colour, s.gate, s.labels, 0).at<cv::Vec3b>(580, 20),
            cv::Vec3b(10, 20, 30));
  EXPECT_THROW(AnnotatePreview(cv::Mat(10, 10, CV_8UC2), s.gate, s.labels), std::invalid_argument);
  EXPECT_THROW(AnnotatePreview(cv::Mat(10, 10, CV_32FC1), s.gate, s.labels), std::invalid_argument);
  EXPECT_THROW(AnnotatePreview(cv::Mat(), s.gate, s.labels), std::invalid_argument);
}

TEST(Preview, WritesAcceptedFramesOnlyAsJpegUnderPreviews) {
  EXPECT_EQ(PreviewFileName("step1/0003.png"), "step1_0003.jpg");
  EXPECT_EQ(PreviewFileName("step2/0010.png"), "step2_0010.jpg");
  const fs::path dir = fs::path(::testing::TempDir()) / "preview_write";
  fs::remove_all(dir);
  Synthetic s;
  const cv::Mat annotated = AnnotatePreview(s.image, s.gate, s.labels);
  const fs::path written = WritePreview(dir, "step2/0004.png", annotated);
  EXPECT_EQ(written, dir / "previews" / "step2_0004.jpg");
  const cv::Mat back = cv::imread(written.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(back.empty());
  EXPECT_EQ(back.size(), annotated.size());
  EXPECT_LT(cv::norm(back, annotated, cv::NORM_L1) / back.total(), 10.0);  // JPEG, not garbage

  std::vector<std::string> warnings;
  FrameObserver writer =
      MakePreviewWriter(dir, dataset::BoardSpec{4, 3, 10}, dataset::BoardSpec{13, 8, 10},
                        [&](const std::string& w) { warnings.push_back(w); });
  FrameReport r;
  r.step = 1;
  r.file = "step1/0001.png";
  r.gate = &s.gate;
  r.image = &s.image;
  r.accepted = false;
  r.final = true;
  writer(r);  // rejected: no preview
  EXPECT_FALSE(fs::exists(dir / "previews" / "step1_0001.jpg"));
  r.accepted = true;
  writer(r);
  EXPECT_TRUE(fs::exists(dir / "previews" / "step1_0001.jpg"));
  r.file = "step1/0002.png";
  r.gate = nullptr;  // gate off
  writer(r);
  EXPECT_TRUE(fs::exists(dir / "previews" / "step1_0002.jpg"));
  EXPECT_TRUE(warnings.empty());
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir / "previews")) {
    ++files;
    EXPECT_EQ(e.path().extension(), ".jpg") << e.path();  // no temporaries left
  }
  EXPECT_EQ(files, 3u);
}

TEST(Preview, MarksWhatTheGateFoundOnARenderedStep1Frame) {
  sim::SimOptions o;
  o.seed = 3;
  o.step1.poses = 4;
  o.triggers.max_triggers = 18;
  const sim::RigSimulator sim(o);
  const dataset::Recording plan = sim.MakeRecording(false);
  const cv::Mat frame = sim.RenderStep1Frame(0);
  const GateResult g = CheckFrame(frame, 1, static_cast<int>(plan.step1[0].beams.size()),
                                  plan.world_board, plan.sliding_board, GateOptions{});
  ASSERT_TRUE(g.accepted) << g.reason;
  ASSERT_EQ(g.boards.size(), 2u);
  const cv::Mat out = AnnotatePreview(
      frame, g, MakePreviewLabels(plan.step1[0].file, 1, plan.world_board, plan.sliding_board), 0);
  cv::Mat plain;
  cv::cvtColor(frame, plain, cv::COLOR_GRAY2BGR);
  for (const auto& d : g.dots) EXPECT_GT(ChangedAround(plain, out, d.px, 3), 0);
  for (const auto& b : g.boards) {
    ASSERT_TRUE(b.has_value());
    EXPECT_GT(ChangedAround(plain, out, b->corners_px.front(), 3), 0);
    EXPECT_GT(ChangedAround(plain, out, b->corners_px.back(), 3), 0);
  }
}

}  // namespace
}  // namespace msmcal::orchestrator
