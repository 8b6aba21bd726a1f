// One test (or a few) per stage of the solver (processing/solver/stages/), on small synthetic
// inputs built here: no images except for the exposure averaging.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>
#include <random>

#include "processing/geometry/mirror_frame.h"
#include "processing/solver/diagnostics.h"
#include "processing/solver/stages/estimate.h"
#include "processing/solver/stages/exposures.h"
#include "processing/solver/stages/measure.h"
#include "processing/solver/stages/mirror0.h"
#include "processing/solver/stages/step1_beams.h"
#include "processing/solver/stages/step2_groups.h"
#include "processing/solver/stages/triggers.h"
#include "processing/solver/stages/uncertainty.h"
#include "processing/solver/stages/validation.h"
#include "processing/solver/synthetic_scene.h"

namespace msmcal::solver {
namespace {

using dataset::Step2Kind;
using geometry::Line;
using geometry::Plane;
using geometry::Rigid3d;

// ---------------- exposures ----------------

dataset::Recording ExposureRecording() {
  dataset::Recording r;
  r.step1 = {{"step1/0.png", 0, {1, 2}},
             {"step1/1.png", 0, {2, 1}},
             {"step1/2.png", 0, {1, 2}},
             {"step1/3.png", 1, {1, 2}},
             {"step1/4.png", 0, {1}}};
  r.step2 = {{"step2/0.png", Step2Kind::kNeutral, {}, {1, 2}},
             {"step2/1.png", Step2Kind::kScan, {3, 4}, {1, 2}},
             {"step2/2.png", Step2Kind::kNeutral, {}, {1, 2}},
             {"step2/3.png", Step2Kind::kScan, {4, 3}, {2, 1}},
             {"step2/4.png", Step2Kind::kScan, {5}, {1, 2}}};
  return r;
}

TEST(ExposuresStage, GroupsRepeatedExposuresOfOneScene) {
  const ExposureScenes e = CollapseExposures(ExposureRecording());
  ASSERT_TRUE(e.Collapsed());
  EXPECT_EQ(e.scenes, 3);           // step1 pose 0 {1,2}; step2 neutral; step2 scan {3,4}
  EXPECT_EQ(e.averaged_frames, 7);  // 3 + 2 + 2
  ASSERT_EQ(e.recording.step1.size(), 3u);
  ASSERT_EQ(e.recording.step2.size(), 3u);
  EXPECT_EQ(e.members.at("step1/0.png"),
            (std::vector<std::string>{"step1/0.png", "step1/1.png", "step1/2.png"}));
  EXPECT_EQ(e.members.at("step2/1.png"), (std::vector<std::string>{"step2/1.png", "step2/3.png"}));
  EXPECT_EQ(e.SceneOf("step1/2.png"), "step1/0.png");
  EXPECT_EQ(e.SceneOf("step2/2.png"), "step2/0.png");
  EXPECT_EQ(e.SceneOf("step1/4.png"), "step1/4.png");
  EXPECT_NE(e.Note().find("7 frames are repeated exposures of 3 scene(s)"), std::string::npos);
}

TEST(ExposuresStage, NothingToCollapseLeavesTheRecordingAlone) {
  dataset::Recording r;
  r.step1 = {{"a.png", 0, {1}}, {"b.png", 1, {1}}};
  const ExposureScenes e = CollapseExposures(r);
  EXPECT_FALSE(e.Collapsed());
  EXPECT_TRUE(e.members.empty());
  EXPECT_EQ(e.SceneOf("a.png"), "a.png");
  const cv::Mat img(4, 5, CV_8UC1, cv::Scalar(7));
  const cv::Mat out = LoadScene(
      e, [&](const std::string&) { return img; }, "a.png");
  EXPECT_EQ(out.type(), CV_8UC1);  // as loaded
}

TEST(ExposuresStage, AveragesExposuresPixelByPixelOnTheWideScale) {
  const ExposureScenes e = CollapseExposures(ExposureRecording());
  auto load = [](const std::string& f) {
    const int v = f == "step1/0.png" ? 10 : f == "step1/1.png" ? 20 : f == "step1/2.png" ? 33 : 5;
    cv::Mat m(3, 4, CV_8UC1, cv::Scalar(v));
    m.at<uint8_t>(0, 0) = 255;  // saturated in every exposure
    return m;
  };
  const cv::Mat avg = LoadScene(e, load, "step1/0.png");
  ASSERT_EQ(avg.type(), CV_16UC1);
  EXPECT_EQ(avg.at<uint16_t>(1, 1), 21 * 257);  // mean of 10, 20, 33 on the 16-bit scale
  EXPECT_EQ(avg.at<uint16_t>(0, 0), 65535);     // full scale stays full scale
  const cv::Mat single = LoadScene(e, load, "step1/3.png");  // one exposure: widened only
  ASSERT_EQ(single.type(), CV_16UC1);
  EXPECT_EQ(single.at<uint16_t>(2, 3), 5 * 257);
  auto bad = [](const std::string& f) {
    return f == "step1/1.png" ? cv::Mat(2, 2, CV_8UC1, cv::Scalar(0)) : cv::Mat(3, 4, CV_8UC1);
  };
  EXPECT_THROW(LoadScene(e, bad, "step1/0.png"), SolveError);
}

// ---------------- step 1: beam labels ----------------

struct Step1Scene {
  std::vector<Line> beams;
  std::vector<Rigid3d> world_from_pose;
  std::vector<Step1View> views;
  std::vector<std::vector<int>> truth;  // per view, beam per dot
  Eigen::Vector3d sliding_z = Eigen::Vector3d::Zero();
  BeamTable table;
};

// Three beams travelling along +Z of {W} (roughly), a plate at 4 poses along them (tilted a
// little); identification frames (one beam) at pose 0, then frames with all beams whose dots
// come in a shuffled order.
Step1Scene MakeStep1Scene() {
  Step1Scene s;
  s.beams = {Line::FromPointDirection({0, 0, 0}, {0.02, 0.01, 1}),
             Line::FromPointDirection({30, 5, 0}, {-0.05, 0.0, 1}),
             Line::FromPointDirection({10, 25, 0}, {0.0, -0.06, 1})};
  s.table = MakeBeamTable({{7, dataset::BeamRole::kEstimate},
                           {8, dataset::BeamRole::kEstimate},
                           {9, dataset::BeamRole::kValidate}});
  std::mt19937 rng(5);
  for (int l = 0; l < 4; ++l) {
    const Eigen::Matrix3d r = (Eigen::AngleAxisd(0.05 * l, Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(-0.03 * l, Eigen::Vector3d::UnitY()))
                                  .toRotationMatrix();
    s.world_from_pose.emplace_back(r, Eigen::Vector3d(0, 0, 100 + 60 * l));
    s.sliding_z += r.col(2);
  }
  auto dot_of = [&](int b, int l) {
    const Plane plane =
        geometry::TransformPlane(s.world_from_pose[l], Plane{Eigen::Vector3d::UnitZ(), 0});
    return *geometry::IntersectLinePlane(s.beams[b], plane);
  };
  auto add = [&](int l, std::vector<int> beams_in_dot_order, std::vector<int> listed) {
    Step1View v;
    v.file = "step1/" + std::to_string(s.views.size()) + ".png";
    v.pose = l;
    v.beams = listed;
    for (int b : beams_in_dot_order) {
      v.dots_in_world.push_back(dot_of(b, l));
      vision::Dot d;
      d.px = Eigen::Vector2d(100 + b, 200 + l);
      d.cov_px2 = Eigen::Matrix2d::Identity() * 0.01;
      v.dots.push_back(d);
    }
    s.views.push_back(v);
    s.truth.push_back(beams_in_dot_order);
  };
  for (int b = 0; b < 3; ++b) add(0, {b}, {b});
  for (int l = 1; l < 4; ++l) {
    std::vector<int> order = {0, 1, 2};
    std::shuffle(order.begin(), order.end(), rng);
    add(l, order, {0, 1, 2});
  }
  return s;
}

TEST(Step1Stage, LabelsDotsWithTheirBeamsAndFitsTheBeams) {
  const Step1Scene s = MakeStep1Scene();
  const BeamLabels out = LabelBeams(s.views, s.world_from_pose, s.sliding_z, s.table);
  ASSERT_TRUE(out.log.error.empty()) << out.log.error;
  EXPECT_TRUE(out.log.dropped.empty());
  ASSERT_EQ(out.label.size(), s.views.size());
  for (size_t k = 0; k < s.views.size(); ++k) EXPECT_EQ(out.label[k], s.truth[k]) << k;
  EXPECT_EQ(out.sliding_dots.size(), 12u);
  ASSERT_EQ(out.beams.size(), 3u);
  for (int b = 0; b < 3; ++b) {
    EXPECT_GT(std::abs(out.beams[b].v.dot(s.beams[b].v)), 1 - 1e-12) << b;
    EXPECT_GT(out.beams[b].v.dot(s.sliding_z), 0) << b;  // travels into the plate
    EXPECT_LT((out.beams[b].m - s.beams[b].m).norm(), 1e-9) << b;
  }
}

// A stray blob counted as one of a frame's dots (scene 4 of the randomised suite: a junk blob
// replaced a beam's dot): the beams' consensus lines leave it unlabelled and keep the frame's
// other dots; no line is pulled off, so no other frame looks wrong.
TEST(Step1Stage, LeavesAStrayBlobUnlabelledAndKeepsTheFramesOtherDots) {
  Step1Scene s = MakeStep1Scene();
  s.views[4].dots_in_world[1] += Eigen::Vector3d(4, 0, 0);
  const BeamLabels out = LabelBeams(s.views, s.world_from_pose, s.sliding_z, s.table);
  ASSERT_TRUE(out.log.error.empty()) << out.log.error;
  EXPECT_TRUE(out.log.dropped.empty());
  std::vector<int> expected = s.truth[4];
  expected[1] = -1;
  EXPECT_EQ(out.label[4], expected);
  for (size_t k = 0; k < s.views.size(); ++k) {
    if (k == 4) continue;
    EXPECT_EQ(out.label[k], s.truth[k]) << k;
  }
  EXPECT_EQ(out.sliding_dots.size(), 11u);
  for (int b = 0; b < 3; ++b) EXPECT_LT((out.beams[b].m - s.beams[b].m).norm(), 1e-9) << b;
}

// More candidates than beams (surplus blobs kept for the lines to choose), and fewer (a dot
// not found): each real dot gets its beam, the surplus none.
TEST(Step1Stage, LabelsFramesWithSurplusCandidatesOrAMissingDot) {
  Step1Scene s = MakeStep1Scene();
  Step1View& surplus = s.views[4];  // pose 2
  const Eigen::Vector3d stray = surplus.dots_in_world[0] + Eigen::Vector3d(0, 9, 0);
  const vision::Dot stray_dot = surplus.dots[0];
  surplus.dots_in_world.push_back(stray);
  surplus.dots.push_back(stray_dot);
  std::vector<int> surplus_truth = s.truth[4];
  surplus_truth.push_back(-1);
  Step1View& missing = s.views[5];  // pose 3
  missing.dots_in_world.erase(missing.dots_in_world.begin() + 1);
  missing.dots.erase(missing.dots.begin() + 1);
  std::vector<int> missing_truth = s.truth[5];
  missing_truth.erase(missing_truth.begin() + 1);
  const BeamLabels out = LabelBeams(s.views, s.world_from_pose, s.sliding_z, s.table);
  ASSERT_TRUE(out.log.error.empty()) << out.log.error;
  EXPECT_TRUE(out.log.dropped.empty());
  EXPECT_EQ(out.label[4], surplus_truth);
  EXPECT_EQ(out.label[5], missing_truth);
  EXPECT_EQ(out.sliding_dots.size(), 11u);
  for (int b = 0; b < 3; ++b) EXPECT_LT((out.beams[b].m - s.beams[b].m).norm(), 1e-9) << b;
}

// Measured step 1 frames built from exact projections: a frame whose sliding board was not
// found (a laser spot on a square corner can break the detectors' grid) reads its dot on the
// plate where another frame of its pose found the board; a frame whose pose has no board in
// any frame is dropped and says so. The borrowed corners enter the fit once.
TEST(Step1Stage, AFrameWithoutItsSlidingBoardUsesItsPosesBoard) {
  dataset::Recording rec;
  rec.camera.width = 1280;
  rec.camera.height = 960;
  rec.camera.fx = rec.camera.fy = 1000;
  rec.camera.cx = 640;
  rec.camera.cy = 480;
  rec.world_board = {7, 5, 20};
  rec.sliding_board = {5, 4, 10};
  rec.beams = {{1, dataset::BeamRole::kEstimate}, {2, dataset::BeamRole::kEstimate}};
  rec.step1 = {{"step1/0000.png", 0, {1}},
               {"step1/0001.png", 0, {2}},
               {"step1/0002.png", 1, {1}},
               {"step1/0003.png", 1, {2}},
               {"step1/0004.png", 2, {1}}};
  const Rigid3d c1_from_world(Eigen::Matrix3d::Identity(), Eigen::Vector3d(-60, -40, 600));
  const Rigid3d c1_from_pose[3] = {
      {Eigen::Matrix3d(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY())), {120, -20, 500}},
      {Eigen::Matrix3d(Eigen::AngleAxisd(-0.1, Eigen::Vector3d::UnitY())), {125, -15, 470}},
      {Rigid3d(Eigen::Matrix3d::Identity(), {120, -20, 440})}};
  auto board = [&](const dataset::BoardSpec& spec, const Rigid3d& c1_from_board) {
    vision::CheckerboardDetection d;
    for (int r = 0; r < spec.rows; ++r)
      for (int c = 0; c < spec.cols; ++c)
        d.corners_px.push_back(*rec.camera.Project(
            c1_from_board * Eigen::Vector3d(c * spec.square_mm, r * spec.square_mm, 0)));
    d.square_px = 20;
    d.refine_half_window_px = 5;
    return d;
  };
  // Each frame's dot at the centre of a square of the plate: (1.5, 1.5) or (2.5, 1.5) squares.
  auto dot_at = [&](const Rigid3d& c1_from_board, double c, double r) {
    vision::Dot d;
    d.px = *rec.camera.Project(c1_from_board * Eigen::Vector3d(10 * c, 10 * r, 0));
    d.cov_px2 = 0.01 * Eigen::Matrix2d::Identity();
    d.num_pixels = 30;
    d.fitted = true;
    return d;
  };
  std::vector<ImageMeasurement> measured(rec.step1.size());
  std::vector<FrameDetection> det(rec.step1.size());
  const double dot_col[5] = {1.5, 2.5, 1.5, 2.5, 1.5};
  for (size_t i = 0; i < rec.step1.size(); ++i) {
    const Rigid3d& pose = c1_from_pose[rec.step1[i].pose];
    measured[i].boards = {board(rec.world_board, c1_from_world), std::nullopt};
    if (i != 1 && i != 4) measured[i].boards[1] = board(rec.sliding_board, pose);
    measured[i].dots = {dot_at(pose, dot_col[i], 1.5)};
    measured[i].image_size = cv::Size(1280, 960);
    det[i].file = rec.step1[i].file;
    det[i].boards.resize(2);
  }
  // The measure stage lends frame 1 the board of frame 0 (its pose's first frame that shows
  // it) and counts its dot on the plate; frame 4's pose has no board to lend.
  const vision::BoardSize world_size{7, 5}, sliding_size{5, 4};
  BorrowSlidingBoards({{0, 1}, {2, 3}, {4}},
                      std::vector<std::vector<vision::BoardSize>>(5, {world_size, sliding_size}),
                      {}, &measured);
  ASSERT_TRUE(measured[1].boards[1].has_value());
  EXPECT_TRUE(measured[1].Borrowed(1));
  EXPECT_EQ(measured[1].board_from[1], 0);
  EXPECT_EQ(measured[1].dots_on_plane, 1u);
  EXPECT_EQ(measured[1].boards[1]->corners_px, measured[0].boards[1]->corners_px);
  EXPECT_FALSE(measured[0].Borrowed(1) || measured[2].Borrowed(1) || measured[3].Borrowed(1));
  EXPECT_FALSE(measured[4].boards[1].has_value());
  // A frame that failed the contrast check (black, blank, saturated) shows no plate: no loan.
  {
    std::vector<ImageMeasurement> black = {measured[0], measured[1]};
    black[1].boards[1].reset();
    black[1].board_from.clear();
    black[1].board_attempts = {{},
                               {{vision::BoardMethod::kContrastCheck, 0.25, false, false, "", {}}}};
    BorrowSlidingBoards({{0, 1}},
                        std::vector<std::vector<vision::BoardSize>>(2, {world_size, sliding_size}),
                        {}, &black);
    EXPECT_FALSE(black[1].boards[1].has_value());
  }
  const Step1Frames out = MeasureStep1Frames(rec, measured, det, MakeBeamTable(rec.beams), {});
  ASSERT_TRUE(out.log.error.empty()) << out.log.error;
  ASSERT_EQ(out.views.size(), 4u);
  EXPECT_EQ(out.num_poses, 2);
  const Step1View& borrowed = out.views[1];
  EXPECT_EQ(borrowed.file, "step1/0001.png");
  EXPECT_EQ(borrowed.pose, out.views[0].pose);
  ASSERT_EQ(borrowed.dots_in_world.size(), 1u);
  const Eigen::Vector3d truth =
      c1_from_world.Inverse() * (c1_from_pose[0] * Eigen::Vector3d(25, 15, 0));
  EXPECT_LT((borrowed.dots_in_world[0] - truth).norm(), 1e-6);
  EXPECT_TRUE(out.detections[1].partial);
  EXPECT_NE(out.detections[1].note.find("step1/0000.png"), std::string::npos)
      << out.detections[1].note;
  int sliding_sets = 0;
  for (const auto& c : out.corners) sliding_sets += c.view == BoardView::kC1Sliding ? 1 : 0;
  EXPECT_EQ(sliding_sets, 3);  // frames 0, 2 and 3: none for the borrowing frame
  ASSERT_EQ(out.log.dropped.size(), 1u);
  EXPECT_EQ(out.log.dropped[0].file, "step1/0004.png");
  EXPECT_NE(out.log.dropped[0].reason.find("not found in this or any other frame of pose 2"),
            std::string::npos)
      << out.log.dropped[0].reason;
}

// dot_margin_from_data: a plate whose spots land six squares beside its pattern (beyond
// step1_dot_margin_squares = 3) widens step 1 to the sliding board's whole plane; a stray blob
// far from the pattern in frames whose dots lie within the margin does not; off, nothing widens.
TEST(MeasureStage, DotsBesideThePatternWidenTheStepToItsBoardsWholePlane) {
  const vision::BoardSize world{7, 5}, sliding{5, 4};
  auto board = [](vision::BoardSize size, Eigen::Vector2d origin, double square) {
    vision::CheckerboardDetection d;
    for (int r = 0; r < size.rows; ++r)
      for (int c = 0; c < size.cols; ++c)
        d.corners_px.push_back(origin + square * Eigen::Vector2d(c + 0.05 * r, 1.0 * r));
    d.square_px = square;
    return d;
  };
  auto dot = [](Eigen::Vector2d px) {
    vision::Dot d;
    d.px = d.centroid_px = px;
    d.scatter_px2 = 2.0 * Eigen::Matrix2d::Identity();
    d.cov_px2 = 0.01 * Eigen::Matrix2d::Identity();
    d.num_pixels = 30;
    d.fitted = true;
    return d;
  };
  const auto w = board(world, {100, 80}, 20), s = board(sliding, {300, 500}, 20);
  // Sliding board (c, r) -> pixel: origin + 20 (c + 0.05 r, r).
  auto on_plate = [](double c, double r) -> Eigen::Vector2d {
    return Eigen::Vector2d(300, 500) + 20 * Eigen::Vector2d(c + 0.05 * r, 1.0 * r);
  };
  const std::vector<std::vector<vision::BoardSize>> sizes(4, {world, sliding});
  const std::vector<int> expected = {1, 1, 1, 0};
  auto frames = [&](const std::vector<std::vector<Eigen::Vector2d>>& dots_px) {
    std::vector<ImageMeasurement> m(dots_px.size());
    for (size_t i = 0; i < m.size(); ++i) {
      m[i].boards = {w, s};
      for (const auto& p : dots_px[i]) m[i].dots.push_back(dot(p));
      m[i].image_size = cv::Size(1200, 900);
      // As the first pass leaves it: counted within the options' margins.
      RegionRejections r;
      m[i].dots_on_plane = DotsOnHostPlane(m[i].dots, m[i], sizes[i], PipelineOptions{}, &r).size();
    }
    return m;
  };
  PipelineOptions o;
  ASSERT_DOUBLE_EQ(o.step1_dot_margin_squares, 3);
  {
    auto m = frames({{on_plate(11, 1)}, {on_plate(11, 2)}, {on_plate(10, 1.5)}, {}});
    std::vector<std::string> notes;
    const PipelineOptions got = ResolveDotMargins(sizes, expected, o, &m, &notes);
    EXPECT_TRUE(std::isinf(got.step1_dot_margin_squares));
    EXPECT_EQ(got.step2_dot_margin_squares, o.step2_dot_margin_squares);
    for (size_t i = 0; i < 3; ++i) EXPECT_EQ(m[i].dots_on_plane, 1u) << i;
    ASSERT_EQ(notes.size(), 1u);
    EXPECT_NE(notes[0].find("step1_dot_margin_squares (3)"), std::string::npos) << notes[0];
    EXPECT_NE(notes[0].find("4 of 4 frames"), std::string::npos) << notes[0];
    // Off: the margin stays, the counts too.
    PipelineOptions off = o;
    off.dot_margin_from_data = false;
    auto m2 = frames({{on_plate(11, 1)}, {on_plate(11, 2)}, {on_plate(10, 1.5)}, {}});
    notes.clear();
    EXPECT_EQ(ResolveDotMargins(sizes, expected, off, &m2, &notes).step1_dot_margin_squares, 3);
    EXPECT_TRUE(notes.empty());
  }
  {
    // Dots on the plate within the margin, a blob far out in every frame (a glint): stays.
    auto m = frames({{on_plate(2, 1), on_plate(25, 1)},
                     {on_plate(6, 2), on_plate(25, 1)},
                     {on_plate(1, 1.5), on_plate(25, 1)},
                     {on_plate(25, 1)}});
    std::vector<std::string> notes;
    const PipelineOptions got = ResolveDotMargins(sizes, expected, o, &m, &notes);
    EXPECT_EQ(got.step1_dot_margin_squares, 3);
    EXPECT_TRUE(notes.empty());
  }
}

// The hint names the refusal that explains the missing dots: blobs refused on the board's
// plane passed every image test, so they win over the image tests' counts (board residue:
// hundreds of small or elongated blobs); without them, the largest image-level count.
TEST(DropSummaryTest, HintNamesTheSpotsRefusedOnThePlaneOverBoardResidue) {
  auto frame = [](int off_plane) {
    FrameDetection d;
    d.file = "step1/0001.png";
    d.step = "step1";
    d.reason = "found 0 laser dots, expected 3 (one per listed beam)";
    d.dots_found = 0;
    d.dots_expected = 3;
    d.rejected.elongated = 120;
    d.rejected.too_small = 60;
    d.off_plane = off_plane;
    return d;
  };
  const DropSummary beside = SummariseDrops({frame(3), frame(3)});
  EXPECT_EQ(beside.dropped, 2);
  EXPECT_NE(beside.hint.find("off the board's plane in 2 of 2 frames"), std::string::npos)
      << beside.hint;
  const DropSummary residue = SummariseDrops({frame(0), frame(0)});
  EXPECT_NE(residue.hint.find("dots.max_elongation"), std::string::npos) << residue.hint;
}

TEST(StageHelpers, BestInjectionLeavesCostlyItemsWithoutASlot) {
  // Items 0, 1 fit slots 2, 0; item 2 fits nothing under the threshold; slot 1 is surplus.
  const double c[3][3] = {{5, 4, 0.1}, {0.2, 3, 6}, {7, 8, 9}};
  auto cost = [&](int i, int slot) { return c[i][slot]; };
  EXPECT_EQ(BestInjection(3, 3, cost, 1.0), (std::vector<int>{2, 0, -1}));
  // A larger threshold lets item 2 take the slot left over.
  EXPECT_EQ(BestInjection(3, 3, cost, 100.0), (std::vector<int>{2, 0, 1}));
  // Fewer slots than items: the cheapest use them.
  EXPECT_EQ(BestInjection(3, 1, cost, 100.0), (std::vector<int>{-1, 0, -1}));
  EXPECT_EQ(BestInjection(0, 2, cost, 1.0), std::vector<int>{});
}

TEST(Step1Stage, FailsWhenABeamHasOnePose) {
  Step1Scene s = MakeStep1Scene();
  s.views.resize(3);  // identification frames only: every beam at pose 0
  const BeamLabels out = LabelBeams(s.views, s.world_from_pose, s.sliding_z, s.table);
  EXPECT_EQ(out.log.error, "step1: beam 7 has dots on 1 sliding pose(s); needs >= 2");
}

// ---------------- step 2: reflection groups ----------------

SyntheticSceneOptions SmallScene() {
  SyntheticSceneOptions o;
  o.num_planes = 8;
  o.num_poses = 4;
  o.seed = 11;
  return o;
}

BeamTable SceneBeams(const SyntheticScene& sc) {
  std::vector<dataset::BeamSpec> specs;
  for (size_t b = 0; b < sc.truth.beams.size(); ++b)
    specs.push_back(
        {static_cast<int>(b), std::count(sc.estimate_beams.begin(), sc.estimate_beams.end(), b)
                                  ? dataset::BeamRole::kEstimate
                                  : dataset::BeamRole::kValidate});
  return MakeBeamTable(specs);
}

// A frame showing planes `planes` (its triggers 100 + plane) with every beam's exact dot, in a
// shuffled order; `truth[dot] = {plane, beam}`.
Step2View FrameOfPlanes(const SyntheticScene& sc, const std::vector<int>& planes, int index,
                        std::vector<std::pair<int, int>>* truth) {
  Step2View v;
  v.index = index;
  v.frame.file = "step2/" + std::to_string(index) + ".png";
  v.frame.kind = Step2Kind::kScan;
  for (int p : planes) v.frame.triggers.push_back(100 + p);
  for (size_t b = 0; b < sc.truth.beams.size(); ++b) v.frame.beams.push_back(static_cast<int>(b));
  for (int p : planes)
    for (size_t b = 0; b < sc.truth.beams.size(); ++b) truth->push_back({p, static_cast<int>(b)});
  std::mt19937 rng(index + 1);
  std::shuffle(truth->begin(), truth->end(), rng);
  for (const auto& [p, b] : *truth) {
    vision::Dot d;
    d.px = *PredictReflectedDot(sc.obs.camera, sc.truth.c2_from_world, sc.truth.beams[b],
                                sc.truth.planes[p]);
    d.cov_px2 = Eigen::Matrix2d::Identity() * 0.01;
    v.dots.push_back(d);
    v.dots_in_world.push_back(*BackProjectToBoard(sc.obs.camera, sc.truth.c2_from_world, d.px));
    v.near_edge.push_back(false);
  }
  return v;
}

TEST(Step2Stage, GroupsReflectedDotsIntoTheirMirrorPlanes) {
  const SyntheticScene sc = MakeSyntheticScene(SmallScene());
  ASSERT_EQ(sc.truth.beams.size(), 3u);
  std::vector<std::vector<std::pair<int, int>>> truth(2);
  const std::vector<Step2View> views = {FrameOfPlanes(sc, {0, 1, 2}, 0, &truth[0]),
                                        FrameOfPlanes(sc, {3}, 1, &truth[1])};
  const ReflectionGroups out = GroupReflections(views, sc.truth.beams, SceneBeams(sc),
                                                sc.obs.camera, sc.truth.c2_from_world, {});
  ASSERT_TRUE(out.log.error.empty()) << out.log.error;
  EXPECT_TRUE(out.log.dropped.empty());
  EXPECT_TRUE(out.recovered.empty());
  ASSERT_EQ(out.groups.size(), 4u);
  for (const Group& g : out.groups) {
    ASSERT_EQ(g.dot_of_beam.size(), 3u);
    const int plane = truth[g.frame][g.dot_of_beam.begin()->second].first;
    for (const auto& [b, d] : g.dot_of_beam) {
      EXPECT_EQ(truth[g.frame][d].first, plane);  // every dot of the group from one plane
      EXPECT_EQ(truth[g.frame][d].second, b);     // and of the beam it is assigned to
    }
    EXPECT_LT((g.plane.n - sc.truth.planes[plane].n).norm(), 1e-6);
    EXPECT_NEAR(g.plane.d, sc.truth.planes[plane].d, 1e-3);
  }
}

TEST(Step2Stage, DropsAFrameWhoseDotsFitNoPlane) {
  const SyntheticScene sc = MakeSyntheticScene(SmallScene());
  std::vector<std::pair<int, int>> truth;
  Step2View v = FrameOfPlanes(sc, {0}, 0, &truth);
  for (auto& d : v.dots) d.px += Eigen::Vector2d(40, -30) * (&d - v.dots.data());
  const ReflectionGroups out = GroupReflections({v}, sc.truth.beams, SceneBeams(sc), sc.obs.camera,
                                                sc.truth.c2_from_world, {});
  EXPECT_TRUE(out.groups.empty());
  ASSERT_EQ(out.log.dropped.size(), 1u);
  EXPECT_NE(out.log.dropped[0].reason.find("could group only 0 of 1"), std::string::npos);
}

// ---------------- triggers ----------------

// Multi-trigger frames (3 triggers each, groups shuffled within a frame) sampled from the
// drive-phase model alpha = 3 sin(wf t) + 0.5 cos(wf t), beta = 2 sin(ws t) (deg).
struct TriggerCase {
  double fast_hz = 7.3, slow_hz = 0.61;
  std::vector<TriggerFrame> frames;
  std::vector<TriggerGroup> groups;
  std::vector<int> truth;  // slot per group
  Eigen::Vector2d Model(double t) const {
    return Eigen::Vector2d(
        3 * std::sin(2 * M_PI * fast_hz * t) + 0.5 * std::cos(2 * M_PI * fast_hz * t),
        2 * std::sin(2 * M_PI * slow_hz * t));
  }
};
TriggerCase MakeTriggerCase(int num_frames, double spacing_s, double drift_s, unsigned seed) {
  TriggerCase c;
  std::mt19937 rng(seed);
  for (int f = 0; f < num_frames; ++f) {
    TriggerFrame fr;
    for (int s = 0; s < 3; ++s) fr.t_s.push_back(spacing_s * (3 * f + s) + drift_s * f * f);
    std::vector<int> order = {0, 1, 2};
    std::shuffle(order.begin(), order.end(), rng);
    for (int s : order) {
      c.groups.push_back({f, c.Model(fr.t_s[s])});
      c.truth.push_back(s);
    }
    c.frames.push_back(fr);
  }
  return c;
}

TEST(TriggersStage, RecoversAKnownTriggerAssignment) {
  const TriggerCase c = MakeTriggerCase(8, 0.013, 0.0021, 3);
  std::string note;
  TriggerModel fitted;
  const std::vector<int> slots = AssignTriggers(c.frames, c.groups, {Eigen::Vector2d::Zero()},
                                                c.fast_hz, c.slow_hz, {}, &note, &fitted);
  EXPECT_EQ(slots, c.truth);
  EXPECT_NE(note.find("24 groups in 8 multi-trigger frames"), std::string::npos) << note;
  EXPECT_LT((fitted.Predict(0.2, true) - c.Model(0.2)).norm(), 1e-6);
}

// Two triggers' dots close together can pair wrongly into a plane tens of degrees off: that
// plane gets no slot (-1) and does not pull the model, so every other plane keeps its trigger
// (before the model was refined on the inliers only, one such plane moved them all).
TEST(TriggersStage, APlaneFromAWrongPairingGetsNoSlotAndMovesNoOther) {
  TriggerCase c = MakeTriggerCase(10, 0.011, 0.0017, 5);
  auto& groups = c.groups;
  auto& truth = c.truth;
  groups[22].angles_deg = Eigen::Vector2d(0.27, -120.8);  // frame 7: a wrong pairing
  truth[22] = -1;
  groups[23].angles_deg = Eigen::Vector2d(4.7, 6.5);  // and another, a few degrees off
  truth[23] = -1;
  std::string note;
  const std::vector<int> slots =
      AssignTriggers(c.frames, groups, {Eigen::Vector2d::Zero()}, c.fast_hz, c.slow_hz, {}, &note);
  EXPECT_EQ(slots, truth);
  EXPECT_NE(note.find("over 28 groups (2 more than 0.4 deg off the model left out)"),
            std::string::npos)
      << note;
}

TEST(TriggersStage, CollectsOnePlanePerKindAndTriggerIndex) {
  const SyntheticScene sc = MakeSyntheticScene(SmallScene());
  std::vector<std::pair<int, int>> truth;
  std::vector<Step2View> views = {FrameOfPlanes(sc, {0}, 0, &truth),
                                  FrameOfPlanes(sc, {1}, 1, &truth),
                                  FrameOfPlanes(sc, {2}, 2, &truth)};
  views[0].frame.kind = Step2Kind::kNeutral;
  views[0].frame.triggers.clear();
  views[1].frame.kind = Step2Kind::kFastOnly;
  const BeamTable beams = SceneBeams(sc);
  std::vector<Group> groups;
  for (int f = 0; f < 3; ++f) {
    Group g;
    g.frame = f;
    for (int b = 0; b < 3; ++b) g.dot_of_beam[b] = b;
    groups.push_back(g);
  }
  // One fast-only plane: {0}'s fast axis from it and the neutral plane, when they are tilted
  // apart (at least kMinSingleFastOnlyTiltDeg); here both planes are the same, then 2 deg apart.
  const MirrorPlanes one_fast = CollectMirrorPlanes(views, groups, beams);
  EXPECT_EQ(one_fast.log.error,
            "step2: 1 usable fast_only mirror plane, 0 deg from the neutral: {0}'s fast axis needs "
            "a second fast_only plane or one tilted at least 0.5 deg from the neutral");
  groups[1].plane.n =
      Eigen::AngleAxisd(2 * M_PI / 180, Eigen::Vector3d::UnitX()) * groups[0].plane.n;
  const MirrorPlanes tilted = CollectMirrorPlanes(views, groups, beams);
  EXPECT_TRUE(tilted.log.error.empty()) << tilted.log.error;
  ASSERT_EQ(tilted.log.notes.size(), 1u);
  EXPECT_EQ(tilted.log.notes[0].rfind("step2: 1 usable fast_only mirror plane, 2 deg from the "
                                      "neutral: {0}'s fast axis from it and the neutral plane",
                                      0),
            0u)
      << tilted.log.notes[0];
  views[2].frame.kind = Step2Kind::kFastOnly;
  groups.push_back(groups[2]);  // the same (kind, j) again: the same plane
  const MirrorPlanes out = CollectMirrorPlanes(views, groups, beams);
  EXPECT_TRUE(out.log.error.empty()) << out.log.error;
  ASSERT_EQ(out.keys.size(), 3u);
  EXPECT_EQ(out.keys[0], std::make_pair(Step2Kind::kNeutral, -1));
  EXPECT_EQ(out.keys[1], std::make_pair(Step2Kind::kFastOnly, 101));
  EXPECT_EQ(out.num_fast_only, 2);
  EXPECT_EQ(out.estimate_dots.size(), 4u * 2);  // two estimate beams per group
  EXPECT_EQ(out.validation_dots.size(), 4u);
  EXPECT_EQ(out.estimate_dots.back().plane, 2);
}

// ---------------- estimate, {0}, uncertainty, validation ----------------

TEST(EstimateStage, MergesRepeatedViewsOverTheirClearCorners) {
  CornerSet a{BoardView::kC2World, -1, {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {2, 0, 0}}, {}};
  a.px = {{10, 10}, {20, 10}, {10, 20}, {20, 20}, {30, 10}};
  CornerSet b = a;
  for (auto& p : b.px) p += Eigen::Vector2d(1, -1);
  int dropped = -1;
  const auto merged = MergeRepeatedViews({a, b}, {{1, 1, 1, 1, 0}, {1, 1, 1, 1, 0}}, &dropped);
  ASSERT_EQ(merged.size(), 1u);
  EXPECT_EQ(dropped, 1);  // the corner no frame sees clear
  ASSERT_EQ(merged[0].px.size(), 4u);
  EXPECT_EQ(merged[0].px[0], Eigen::Vector2d(10.5, 9.5));
}

// A static board seen in six frames (sigma 0.02 px per axis): frame 3 shifted whole by
// (0.3, -0.2) px (the camera moved a little) keeps every corner; frames 4 and 5 put corners 7
// and 8 0.4 px off (a plate over the squares next to them): those four observations are marked,
// nothing else. A corner not clear in a frame stays so and is not counted; a view of two frames
// is not judged.
TEST(EstimateStage, CornersThatOneFramePutsOffTheirViewsConsensusAreMarked) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.02);
  CornerSet base{BoardView::kC1World, -1, {}, {}};
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 5; ++c) {
      base.points_in_board.emplace_back(10.0 * c, 10.0 * r, 0);
      base.px.emplace_back(100 + 15.0 * c, 200 + 15.0 * r);
    }
  std::vector<CornerSet> sets;
  for (int f = 0; f < 6; ++f) {
    CornerSet cs = base;
    for (auto& p : cs.px) p += Eigen::Vector2d(noise(rng), noise(rng));
    if (f == 3)
      for (auto& p : cs.px) p += Eigen::Vector2d(0.3, -0.2);
    if (f >= 4) {
      cs.px[7] += Eigen::Vector2d(0.4, 0);
      cs.px[8] += Eigen::Vector2d(0, -0.4);
    }
    sets.push_back(cs);
  }
  CornerSet other{BoardView::kC1Sliding, 0, base.points_in_board, base.px};
  sets.push_back(other);
  other.px[0] += Eigen::Vector2d(2, 0);  // two frames of a view: not judged
  sets.push_back(other);
  std::vector<std::vector<char>> clear(sets.size(), std::vector<char>(base.px.size(), 1));
  clear[0][5] = 0;
  const CornerConsistency c = MarkInconsistentCorners(sets, &clear);
  EXPECT_EQ(c.marked, 4);
  EXPECT_EQ(c.frames_affected, 2);
  EXPECT_GT(c.max_threshold_px, 0.05);  // 5 sigma of 0.02 px noise, ~0.1 px
  EXPECT_LT(c.max_threshold_px, 0.2);
  for (size_t k = 0; k < sets.size(); ++k)
    for (size_t i = 0; i < base.px.size(); ++i) {
      const bool off = k >= 4 && k <= 5 && (i == 7 || i == 8);
      const bool was_cleared = k == 0 && i == 5;
      EXPECT_EQ(clear[k][i] != 0, !off && !was_cleared) << "frame " << k << " corner " << i;
    }
}

TEST(EstimateStage, MleRecoversTheSyntheticTruthAndHomeFrameHasItsConvention) {
  const SyntheticScene sc = MakeSyntheticScene(SmallScene());
  std::vector<std::vector<char>> clear;
  for (const auto& c : sc.obs.corners) clear.emplace_back(c.px.size(), 1);
  const MleEstimate est = EstimateMle(sc.obs, clear, {});
  ASSERT_TRUE(est.log.error.empty()) << est.log.error;
  ASSERT_TRUE(est.mle.usable);
  for (size_t p = 0; p < sc.truth.planes.size(); ++p)
    EXPECT_LT(geometry::AngleBetween(est.mle.estimate.planes[p].n, sc.truth.planes[p].n), 1e-3);

  // Plane 0 as neutral, 1 and 2 fast-only, the rest scan (trigger j = plane index).
  std::vector<std::pair<Step2Kind, int>> keys = {{Step2Kind::kNeutral, -1}};
  for (int p = 1; p < sc.obs.num_planes; ++p)
    keys.emplace_back(p < 3 ? Step2Kind::kFastOnly : Step2Kind::kScan, p);
  const Mirror0 m0 = EstimateMirror0(keys, est.mle);
  EXPECT_EQ(m0.roles.neutral, 0);
  EXPECT_EQ(m0.roles.fast_only, (std::vector<int>{1, 2}));
  ASSERT_EQ(m0.support_planes.size(), 3u);
  const auto neutral =
      geometry::PoseFromWorldPlane(m0.world_from_mirror0, est.mle.estimate.planes[0]);
  EXPECT_NEAR(neutral.alpha_rad, 0, 1e-12);  // the neutral plane is home by definition
  EXPECT_NEAR(neutral.beta_rad, 0, 1e-12);
  EXPECT_NEAR(neutral.trans_mm, 0, 1e-9);

  const Mirror0Covariance cov =
      PropagateMirror0Covariance(m0.roles, est.mle, m0.world_from_mirror0);
  EXPECT_LT((cov.cov - cov.cov.transpose()).norm(), 1e-12 * cov.cov.norm());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(cov.cov);
  EXPECT_GT(es.eigenvalues().minCoeff(), -1e-15);
  EXPECT_GT(cov.cov.trace(), 0);
  const auto rows = ScanPlaneRows(keys, m0.roles, {}, est.mle, m0.world_from_mirror0, cov);
  ASSERT_EQ(rows.size(), static_cast<size_t>(sc.obs.num_planes - 3));
  for (const auto& r : rows) {
    EXPECT_GT(r.sigma_alpha_deg, 0);
    EXPECT_LT(r.sigma_alpha_deg, 0.05);
  }

  std::vector<ReflectedDot> held_out = sc.validation_dots;
  const ValidationResult v =
      ValidateHeldOutBeams(est.obs, held_out, keys, sc.estimate_beams, {0, 1, 2}, est.mle);
  size_t on_scan = 0;
  for (const auto& d : held_out) on_scan += d.plane >= 3;
  EXPECT_EQ(v.details.size(), on_scan);
  EXPECT_LT(v.rms_px, 1.0);
  EXPECT_GT(v.rms_normalised, 0.2);  // errors as large as their predicted covariance says
  EXPECT_LT(v.rms_normalised, 3.0);
}

// The held-out dots of one scene share the estimate's errors (their beam's above all), so their
// marginal normalised errors are correlated; the joint whitening L^-1 e (L L^T the joint
// covariance) gives independent N(0, 1) components when the covariances are honest. Over
// synthetic scenes with noise drawn from the stated covariances: the pooled whitened components
// are standard normal, their per-dot squared norms chi2(2) (39.3 / 86.5 / 98.9 % inside 1, 2, 3
// sigma), consecutive dots uncorrelated, and the joint covariance's diagonal blocks are eq. 10's.
TEST(ValidationStage, JointWhiteningOfHeldOutDotsIsStandardNormalAndIndependent) {
  double sum_w2 = 0, lag_joint = 0, lag_marginal = 0;
  int components = 0, dots = 0, pairs = 0;
  int inside[3] = {0, 0, 0};
  for (uint64_t seed = 1; seed <= 48; ++seed) {
    SyntheticSceneOptions o = SmallScene();
    o.seed = seed;
    o.num_planes = 10;
    if (seed % 2 == 0) {
      // Two held-out beams: their dots on one plane share it (the plane's own covariance).
      o.beam_azimuth_deg.push_back(-8.0);
      o.beam_elevation_deg.push_back(-5.0);
    }
    const SyntheticScene sc = MakeSyntheticScene(o);
    std::vector<std::vector<char>> clear;
    for (const auto& c : sc.obs.corners) clear.emplace_back(c.px.size(), 1);
    MleOptions mo;
    mo.estimate_variance_factors = false;  // the stated covariances are the true ones
    const MleEstimate est = EstimateMle(sc.obs, clear, mo);
    ASSERT_TRUE(est.mle.usable) << seed;
    std::vector<std::pair<Step2Kind, int>> keys;
    for (int p = 0; p < sc.obs.num_planes; ++p) keys.emplace_back(Step2Kind::kScan, p);
    std::vector<int> ids(sc.truth.beams.size());
    for (size_t b = 0; b < ids.size(); ++b) ids[b] = static_cast<int>(b);
    const ValidationResult v =
        ValidateHeldOutBeams(est.obs, sc.validation_dots, keys, sc.estimate_beams, ids, est.mle);
    const int n = static_cast<int>(v.details.size());
    ASSERT_GT(n, 5) << seed;
    ASSERT_EQ(v.joint_cov.rows(), 2 * n);
    double nees = 0;
    for (int i = 0; i < n; ++i) {
      const ValidationDetail& d = v.details[i];
      EXPECT_LT((v.joint_cov.block<2, 2>(2 * i, 2 * i) - d.cov_px2).norm(), 1e-9 * d.cov_px2.norm())
          << seed;
      const Eigen::Vector2d e = d.observed_px - d.predicted_px;
      EXPECT_NEAR(e.norm(), d.row.err_px, 1e-12);
      EXPECT_NEAR(std::sqrt(e.dot(d.cov_px2.inverse() * e) / 2), d.normalised_error, 1e-9);
      const Eigen::Vector2d& w = d.joint_whitened;
      nees += w.squaredNorm();
      sum_w2 += w.squaredNorm();
      components += 2;
      ++dots;
      for (int k = 0; k < 3; ++k) inside[k] += w.squaredNorm() <= (k + 1) * (k + 1);
      if (i > 0 && d.row.beam == v.details[i - 1].row.beam) {
        // Consecutive dots of one beam: products of their whitened components (mean 0 when
        // independent), and of their marginally whitened errors (C_i^-1/2 e_i).
        const ValidationDetail& p = v.details[i - 1];
        lag_joint += w.dot(p.joint_whitened) / 2;
        const Eigen::Vector2d mi = d.cov_px2.llt().matrixL().solve(d.observed_px - d.predicted_px);
        const Eigen::Vector2d mp = p.cov_px2.llt().matrixL().solve(p.observed_px - p.predicted_px);
        lag_marginal += mi.dot(mp) / 2;
        ++pairs;
      }
    }
    EXPECT_NEAR(nees, v.joint_nees, 1e-9 * nees);
  }
  // E[w^2] = 1, sd of the mean sqrt(2 / components).
  EXPECT_NEAR(sum_w2 / components, 1.0, 3 * std::sqrt(2.0 / components)) << components;
  for (int k = 0; k < 3; ++k) {
    const double p = 1 - std::exp(-(k + 1) * (k + 1) / 2.0);
    EXPECT_NEAR(static_cast<double>(inside[k]) / dots, p, 3 * std::sqrt(p * (1 - p) / dots))
        << (k + 1) << " sigma, " << dots << " dots";
  }
  // Correlation of consecutive dots: none once whitened jointly (sd 1 / sqrt(pairs)); clearly
  // positive between the marginal ones (the shared beam error).
  EXPECT_LT(std::abs(lag_joint / pairs), 3 / std::sqrt(static_cast<double>(pairs))) << pairs;
  EXPECT_GT(lag_marginal / pairs, 0.3) << pairs;
  std::printf(
      "held-out dots %d, pairs %d: mean w^2 %.3f, inside 1/2/3 sigma %.3f %.3f %.3f, "
      "lag correlation joint %.3f, marginal %.3f\n",
      dots, pairs, sum_w2 / components, double(inside[0]) / dots, double(inside[1]) / dots,
      double(inside[2]) / dots, lag_joint / pairs, lag_marginal / pairs);
}

}  // namespace
}  // namespace msmcal::solver
