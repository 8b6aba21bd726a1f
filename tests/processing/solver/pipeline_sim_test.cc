// End-to-end: the rig simulator renders a session, the pipeline solves it from the images.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <map>

#include "common/units.h"
#include "mocks/rig/rig_simulator.h"
#include "processing/geometry/mirror_frame.h"
#include "processing/solver/home_frame.h"
#include "processing/solver/pipeline.h"
#include "tests/testing/cached_loader.h"

namespace msmcal::solver {
namespace {

struct SimRun {
  sim::SimOptions options;
  std::unique_ptr<sim::RigSimulator> sim;
  dataset::Recording rec;
  SolveOutput out;
};

// `all_beams_every_pose`: step 1 as the simulator planned it before close dots were taken one
// beam at a time: an all-beams frame at every pose, then the identification frames (same files,
// hence the same noise, as the sessions of the original failures).
// `edit_step2(i, scene)` may change step 2 frame i's scene before it is rendered (same noise).
SimRun RunSimulation(const sim::SimOptions& options, const PipelineOptions& pipeline = {},
                     bool all_beams_every_pose = false,
                     const std::function<void(size_t, sim::Scene*)>& edit_step2 = {}) {
  SimRun r;
  r.options = options;
  r.sim = std::make_unique<sim::RigSimulator>(options);
  r.rec = r.sim->MakeRecording(/*with_hall=*/false);
  if (all_beams_every_pose) {
    std::vector<int> all(options.beams.count);
    for (int b = 0; b < options.beams.count; ++b) all[b] = b + 1;
    auto file = [](size_t i) {
      char buf[32];
      std::snprintf(buf, sizeof(buf), "step1/%04zu.png", i);
      return std::string(buf);
    };
    r.rec.step1.clear();
    for (int l = 0; l < options.step1.poses; ++l)
      r.rec.step1.push_back({file(r.rec.step1.size()), l, all});
    for (int id : all)
      r.rec.step1.push_back({file(r.rec.step1.size()), options.step1.poses - 1, {id}});
  }
  const ImageLoader load = msmcal::testing::CachedLoader([&](const std::string& file) -> cv::Mat {
    for (size_t i = 0; i < r.rec.step1.size(); ++i)
      if (r.rec.step1[i].file == file)
        return r.sim->RenderScene(r.sim->FrameScene(r.rec.step1[i]), i);
    for (size_t i = 0; i < r.rec.step2.size(); ++i)
      if (r.rec.step2[i].file == file) {
        if (!edit_step2) return r.sim->RenderStep2Frame(i);
        sim::Scene scene = r.sim->FrameScene(r.rec.step2[i]);
        edit_step2(i, &scene);
        return r.sim->RenderScene(scene, 100000 + i);
      }
    return cv::Mat();
  });
  r.out = SolveRecording(r.rec, load, pipeline);
  return r;
}

TEST(PipelineSimTest, RecoversBeamsPlanesAndHonestSigmas) {
  sim::SimOptions o;
  o.seed = 3;
  const SimRun r = RunSimulation(o);
  // Unusable frames are skipped with a reason, not fatal (seed 3: two step-1 frames where a
  // checkerboard-junction blob survives the dot filters).
  for (const auto& d : r.out.dropped)
    std::printf("dropped %s: %s\n", d.file.c_str(), d.reason.c_str());
  EXPECT_LE(r.out.dropped.size(), 2u);
  for (const auto& n : r.out.notes) std::printf("note: %s\n", n.c_str());
  // Beams.
  ASSERT_EQ(r.out.beams.size(), r.sim->beams_in_world().size());
  for (const auto& b : r.out.beams) {
    const auto& truth = r.sim->beams_in_world()[b.beam - 1];
    const double err_deg = geometry::AngleBetween(b.v, truth.v) * common::kDegPerRad;
    std::printf("beam %d: direction error %.4f deg, distance %.4f mm\n", b.beam, err_deg,
                truth.Distance(b.p));
    // Beams with role estimate are also constrained by the reflections; the held-out beam only
    // by its sliding-plane dots.
    const bool held_out = b.beam == 3;
    EXPECT_LT(err_deg, held_out ? 0.01 : 0.005) << "beam " << b.beam;  // 0.0034, 0.0012-0.0018
  }
  // Planes: one per scan trigger.
  ASSERT_EQ(r.out.planes.size(), r.sim->triggers().size());
  double sum2 = 0, trans2 = 0;
  Eigen::Vector3d z2 = Eigen::Vector3d::Zero();
  // Truth in the solver's {0} convention (home_frame.h): origin on the true neutral plane.
  std::vector<geometry::Plane> true_scan;
  for (const auto& row : r.out.planes)
    true_scan.push_back(
        r.sim->MirrorPlaneInWorld(r.sim->triggers()[row.j].t_s, sim::DriveMode::kScan));
  const geometry::Rigid3d truth_frame =
      ConventionalTruthFrame(r.sim->world_from_mirror0(), true_scan);
  for (size_t k = 0; k < r.out.planes.size(); ++k) {
    const auto& row = r.out.planes[k];
    const geometry::Plane& truth = true_scan[k];
    const double e = geometry::AngleBetween(row.plane_in_world.n, truth.n) * common::kDegPerRad;
    sum2 += e * e;
    const auto tp = geometry::PoseFromWorldPlane(truth_frame, truth);
    trans2 += std::pow(row.trans_mm - tp.trans_mm, 2);
    z2(0) += std::pow((row.alpha_deg - tp.alpha_rad * common::kDegPerRad) / row.sigma_alpha_deg, 2);
    z2(1) += std::pow((row.beta_deg - tp.beta_rad * common::kDegPerRad) / row.sigma_beta_deg, 2);
    z2(2) += std::pow((row.trans_mm - tp.trans_mm) / row.sigma_trans_mm, 2);
  }
  const double n = static_cast<double>(r.out.planes.size());
  const double rms_deg = std::sqrt(sum2 / n);
  const Eigen::Vector3d z = (z2 / n).cwiseSqrt();
  const double trans_rms_mm = std::sqrt(trans2 / n);
  std::printf(
      "planes %zu: normal RMS %.4f deg; trans vs truth RMS %.4f mm; normalised RMS alpha "
      "%.2f beta %.2f trans %.2f\n",
      r.out.planes.size(), rms_deg, trans_rms_mm, z(0), z(1), z(2));
  std::printf("validation RMS %.4f deg (baseline %.4f), normalised %.2f, spanning %.1f deg\n",
              r.out.rms_validation_deg, r.out.rms_baseline_deg, r.out.rms_normalised_validation,
              r.out.mean_spanning_angle_deg);
  std::printf("variance factors: corners %.3f dots %.3f; %d iterations, %.3f s in Ceres\n",
              r.out.mle.corner_variance_factor, r.out.mle.dot_variance_factor, r.out.mle.iterations,
              r.out.mle.solver_time_s);
  EXPECT_LT(rms_deg, 0.01);  // measured 0.0027
  // Below the paper's best proposed-model error; the held-out beam's own line dominates it.
  EXPECT_LT(r.out.rms_validation_deg, 0.01);  // measured 0.0033 (0.0148 with one exposure)
  // {0} convention: trans from the neutral plane (home_frame.h). With the top-hat centroid a
  // neutral-frame dot on a board corner cost 0.12 mm here; fitted over a measured background
  // (docs/solver.md, "Dots") it is 0.0076 mm.
  EXPECT_LT(trans_rms_mm, 0.02);
  // One scene (measured 1.13 / 1.23 / 1.16); honesty over 8 scenes: solver_honesty_sim_test.
  for (int k = 0; k < 3; ++k) {
    EXPECT_GT(z(k), 0.6) << "component " << k;
    EXPECT_LT(z(k), 1.6) << "component " << k;
  }
}

// Issue 6 (Table I row B-5: pattern B, 27 deg spanning angle, seed 6): step1/0004.png yields the
// expected 3 blobs, but one is not a laser dot (it lies ~40 mm from every beam line), so the
// permutation labels beams 2 and 3 wrongly. Those points tilted beams 2 and 3 by ~1 deg, no
// step 2 multi-trigger frame grouped within max_group_residual_px and the solve failed. The
// step 1 label check drops that frame from the beam fit and the session solves. The real dot
// it displaced was a saturated spot on a light square, which the detector then rejected (more
// than 90 % saturated pixels); it no longer does (the fit places such spots by their flanks), so
// the test restores that limit to keep the label check's scenario.
sim::SimOptions RowB5() {
  sim::SimOptions o;
  o.seed = 6;
  o.beams.spanning_angle_deg = 27.0;
  o.mirror.fast.frequency_hz = 200.0;
  o.mirror.fast.amplitude_vpp = 2.5;
  o.mirror.slow.frequency_hz = 4.0;
  o.mirror.slow.amplitude_vpp = 3.5;
  o.step1.background_frames = false;  // the frames (and their noise) of the original failure
  return o;
}

// Issue 6's row B-5: step1/0004.png shows a stray blob where beam 3's dim dot is. It used to
// mislabel beams 2 and 3 and tilt the beam lines by ~1 deg (then: the frame dropped by the label
// check). The beams are now consensus lines over all poses, so the stray blob lies on none and
// stays unlabelled, the frame's other dots are kept, and no frame is dropped.
TEST(PipelineSimTest, LeavesAStrayStep1BlobOffEveryBeamLine) {
  PipelineOptions p;
  p.dots.max_saturated_fraction = 0.9;
  p.average_exposures = false;  // every frame measured on its own, as then
  const SimRun r = RunSimulation(RowB5(), p, /*all_beams_every_pose=*/true);
  int label_drops = 0;
  for (const auto& d : r.out.dropped) {
    std::printf("dropped %s: %s\n", d.file.c_str(), d.reason.c_str());
    if (d.reason.find("labels inconsistent") != std::string::npos) ++label_drops;
  }
  bool consensus_noted = false;
  for (const auto& n : r.out.notes) {
    std::printf("note: %s\n", n.c_str());
    consensus_noted =
        consensus_noted || n.find("consensus lines over 7 poses (23 of 24") != std::string::npos;
  }
  EXPECT_EQ(label_drops, 0);
  EXPECT_TRUE(consensus_noted) << "one listed beam's dot (the stray blob's frame) unlabelled";
  ASSERT_EQ(r.out.beams.size(), r.sim->beams_in_world().size());
  for (const auto& b : r.out.beams) {
    const auto& truth = r.sim->beams_in_world()[b.beam - 1];
    EXPECT_LT(geometry::AngleBetween(b.v, truth.v) * common::kDegPerRad, 0.03) << "beam " << b.beam;
  }
  EXPECT_EQ(r.out.planes.size(), r.sim->triggers().size());
  EXPECT_LT(r.out.rms_validation_deg, 0.042);
}

// The same session with the default dot options: the saturated spots are kept, the stray blob
// is the fourth (least round) of step1/0004.png, no label is inconsistent and every trigger
// gets its plane.
TEST(PipelineSimTest, KeepsSaturatedSpotsOnLightSquares) {
  const SimRun r = RunSimulation(RowB5(), {}, /*all_beams_every_pose=*/true);
  for (const auto& d : r.out.dropped) {
    std::printf("dropped %s: %s\n", d.file.c_str(), d.reason.c_str());
    EXPECT_EQ(d.reason.find("labels inconsistent"), std::string::npos);
  }
  EXPECT_EQ(r.out.planes.size(), r.sim->triggers().size());
  for (const auto& b : r.out.beams)
    EXPECT_LT(
        geometry::AngleBetween(b.v, r.sim->beams_in_world()[b.beam - 1].v) * common::kDegPerRad,
        0.02)
        << "beam " << b.beam;
}

// 8-bit BGR frames (green spots, weights B 0.20, G 1.0, R 0.12): on light squares the green
// channel saturates while blue and red rise. Green minus max(blue, red) lost those spots and
// step 1 failed; the green channel's top-hat with a per-blob greenness check finds them.
TEST(PipelineSimTest, SolvesColourFrames) {
  sim::SimOptions o;
  o.seed = 1;
  o.render.colour = true;
  const SimRun r = RunSimulation(o);
  for (const auto& d : r.out.dropped)
    std::printf("dropped %s: %s\n", d.file.c_str(), d.reason.c_str());
  for (const auto& b : r.out.beams) {
    const double err_deg =
        geometry::AngleBetween(b.v, r.sim->beams_in_world()[b.beam - 1].v) * common::kDegPerRad;
    std::printf("beam %d: direction error %.4f deg\n", b.beam, err_deg);
    EXPECT_LT(err_deg, b.beam == 3 ? 0.01 : 0.005) << "beam " << b.beam;  // 0.0031, 0.0013-14
  }
  std::printf("%zu planes, validation %.4f deg (baseline %.4f)\n", r.out.planes.size(),
              r.out.rms_validation_deg, r.out.rms_baseline_deg);
  EXPECT_GE(r.out.planes.size() + 2, r.sim->triggers().size());  // measured 60 of 60
  EXPECT_LT(r.out.rms_validation_deg, 0.015);                    // measured 0.0033
  EXPECT_LT(r.out.rms_validation_deg, r.out.rms_baseline_deg);
}

// A scan frame that lost one dot of one trigger (occluded, merged): with the held-out dot
// missing, the two estimate dots left over after the complete triggers are that trigger's by
// elimination; its plane is fitted from them and kept because the drive-phase model predicts
// its angles at the one free trigger time. With an estimate dot missing, the leftover pair is
// an estimate and a held-out dot: no plane from it is kept, and no wrong plane enters.
struct MissingDotRun {
  SimRun run;
  std::string file;
  int j = -1;
};

MissingDotRun RunWithoutDot(int beam) {
  sim::SimOptions o;
  o.seed = 3;
  o.step1.exposures = 1;
  const sim::RigSimulator probe(o);
  size_t frame = 0;
  while (probe.step2_frames()[frame].kind != dataset::Step2Kind::kScan ||
         probe.step2_frames()[frame].triggers.size() < 3)
    ++frame;
  MissingDotRun m;
  m.file = probe.step2_frames()[frame].file;
  m.j = probe.step2_frames()[frame].triggers[1];
  const int j = m.j;
  m.run = RunSimulation(o, {}, false, [&](size_t i, sim::Scene* scene) {
    if (i != frame) return;
    for (size_t k = 0; k < scene->labels.size(); ++k)
      if (scene->labels[k].beam == beam && scene->labels[k].j == j) {
        scene->labels.erase(scene->labels.begin() + k);
        scene->dots.erase(scene->dots.begin() + k);
        return;
      }
  });
  return m;
}

double WorstNormalErrorDeg(const SimRun& r) {
  double worst = 0;
  for (const auto& p : r.out.planes) {
    const auto truth = r.sim->MirrorPlaneInWorld(p.t_s, sim::DriveMode::kScan);
    worst =
        std::max(worst, geometry::AngleBetween(p.plane_in_world.n, truth.n) * common::kDegPerRad);
  }
  return worst;
}

TEST(PipelineSimTest, RecoversATriggerWhoseHeldOutDotIsMissing) {
  const MissingDotRun m = RunWithoutDot(3);
  const std::string want = m.file + ": trigger " + std::to_string(m.j) + " (its held-out dot";
  bool kept = false;
  for (const auto& n : m.run.out.notes) {
    std::printf("note: %s\n", n.c_str());
    kept = kept || (n.rfind(want, 0) == 0 && n.find(": kept") != std::string::npos);
  }
  EXPECT_TRUE(kept);
  EXPECT_EQ(m.run.out.planes.size(), m.run.sim->triggers().size());
  EXPECT_LT(WorstNormalErrorDeg(m.run), 0.02);
}

TEST(PipelineSimTest, NoPlaneFromATriggerWhoseEstimateDotIsMissing) {
  const MissingDotRun m = RunWithoutDot(1);
  for (const auto& n : m.run.out.notes) {
    std::printf("note: %s\n", n.c_str());
    EXPECT_TRUE(n.find("held-out dot missing") == std::string::npos ||
                n.find("not kept") != std::string::npos)
        << n;
  }
  EXPECT_EQ(m.run.out.planes.size() + 1, m.run.sim->triggers().size());
  EXPECT_LT(WorstNormalErrorDeg(m.run), 0.02);
}

// Table I row B-5 (background frames on): where the held-out beam's error comes from. Each of
// its sliding-plane points is rebuilt from the TRUE pixel through the ESTIMATED poses (C1 -> W,
// C1 -> S_l): the line through those points carries the pose error alone (~0.001 deg); the rest
// is the noise of its sliding-plane dots (all saturated on light squares in this scene, sigma
// ~0.03 px). Averaging 3 exposures per step 1 frame (the simulator's default) cuts the beam's
// predicted sigma from 0.0047 to 0.0035 deg and its error from 0.0125 to 0.0052 deg
// (docs/solver.md, "Table I").
double HeldOutSigmaDeg(const SimRun& r, int held) {
  for (size_t b = 0; b < r.out.beams.size(); ++b)
    if (r.out.beams[b].beam == held) {
      const int off = r.out.mle.OffsetBeam(static_cast<int>(b));
      return std::sqrt(r.out.mle.other_cov.block(off, off, 2, 2).trace() / 2) * common::kDegPerRad;
    }
  return 0;
}

TEST(PipelineSimTest, HeldOutBeamErrorBudget) {
  sim::SimOptions o = RowB5();
  o.step1.background_frames = true;
  ASSERT_EQ(o.step1.exposures, 3);
  const SimRun r = RunSimulation(o);
  for (const auto& n : r.out.notes) std::printf("note: %s\n", n.c_str());
  bool averaged = false;
  for (const auto& n : r.out.notes) averaged = averaged || n.rfind("exposures: ", 0) == 0;
  EXPECT_TRUE(averaged);
  {
    sim::SimOptions single = o;
    single.step1.exposures = 1;
    const SimRun r1 = RunSimulation(single);
    const double sd1 = HeldOutSigmaDeg(r1, o.beams.validate_ids[0]);
    const double sd3 = HeldOutSigmaDeg(r, o.beams.validate_ids[0]);
    std::printf("held-out beam's predicted sigma per axis: one exposure %.4f deg, three %.4f deg\n",
                sd1, sd3);
    EXPECT_LT(sd3, 0.8 * sd1);
  }
  const auto& est = r.out.mle.estimate;
  const int held = o.beams.validate_ids[0];
  const geometry::Rigid3d world_from_c1 = est.c1_from_world.Inverse();
  std::vector<Eigen::Vector3d> pose_only, truth_pts;
  for (size_t l = 0; l < r.sim->world_from_sliding().size(); ++l) {
    const auto p_true = r.sim->SlidingDotInWorld(held, static_cast<int>(l));
    ASSERT_TRUE(p_true);
    const geometry::Rigid3d c1_from_sliding_true = r.sim->c1_from_sliding(static_cast<int>(l));
    // The estimated pose of this sliding pose: the one nearest in translation.
    size_t best = 0;
    for (size_t k = 1; k < est.c1_from_sliding.size(); ++k)
      if ((est.c1_from_sliding[k].translation - c1_from_sliding_true.translation).norm() <
          (est.c1_from_sliding[best].translation - c1_from_sliding_true.translation).norm())
        best = k;
    const Eigen::Vector3d p_c1 = r.sim->c1_from_world() * *p_true;
    const auto px = r.sim->camera().Project(p_c1);
    ASSERT_TRUE(px);
    const Eigen::Vector3d ray = r.sim->camera().Unproject(*px);
    const geometry::Plane sliding_in_c1 =
        geometry::TransformPlane(est.c1_from_sliding[best], geometry::Plane{});
    const auto hit = geometry::IntersectRayPlane(Eigen::Vector3d::Zero(), ray, sliding_in_c1);
    ASSERT_TRUE(hit);
    const Eigen::Vector3d p_est = world_from_c1 * *hit;
    const Eigen::Vector3d p_pose_true = r.sim->c1_from_world().Inverse() * *hit;
    std::printf(
        "pose %zu: pose-only error %.4f mm (C1->W alone %.4f mm), pose translation error "
        "%.4f mm\n",
        l, (p_est - *p_true).norm(), (p_est - p_pose_true).norm(),
        (est.c1_from_sliding[best].translation - c1_from_sliding_true.translation).norm());
    pose_only.push_back(p_est);
    truth_pts.push_back(*p_true);
    for (const auto& b : r.out.beams)
      if (b.beam == held) {
        const geometry::Line beam_c1 = geometry::TransformLine(
            est.c1_from_world, geometry::Line::FromPointDirection(b.p, b.v));
        const auto on = geometry::IntersectLinePlane(beam_c1, sliding_in_c1);
        const auto pred = r.sim->camera().Project(*on);
        std::printf("   estimated beam's dot - true pixel: (%.4f, %.4f) px\n", (*pred - *px).x(),
                    (*pred - *px).y());
      }
  }
  const auto& truth = r.sim->beams_in_world()[held - 1];
  const geometry::Line pose_line = geometry::FitLine(pose_only);
  const geometry::Line truth_fit = geometry::FitLine(truth_pts);
  double est_deg = -1, sd_deg = 0;
  for (size_t b = 0; b < r.out.beams.size(); ++b)
    if (r.out.beams[b].beam == held) {
      est_deg = geometry::AngleBetween(r.out.beams[b].v, truth.v) * common::kDegPerRad;
      const int off = r.out.mle.OffsetBeam(static_cast<int>(b));
      sd_deg =
          std::sqrt(r.out.mle.other_cov.block(off, off, 2, 2).trace() / 2) * common::kDegPerRad;
    }
  // FitLine orients its direction by the points' order; compare as lines.
  auto line_deg = [&](const Eigen::Vector3d& v) {
    return std::acos(std::min(1.0, std::abs(v.dot(truth.v)))) * common::kDegPerRad;
  };
  const double pose_deg = line_deg(pose_line.v);
  std::printf(
      "held-out beam: estimated %.4f deg (predicted sigma per axis %.4f deg); line "
      "through pose-only points %.4f deg; through true points %.5f deg\n",
      est_deg, sd_deg, pose_deg, line_deg(truth_fit.v));
  EXPECT_LT(line_deg(truth_fit.v), 1e-6);
  EXPECT_LT(pose_deg, 0.003);
  EXPECT_LT(est_deg, 3.5 * sd_deg);  // 2 dof: chi2 > 12.25 has probability 0.2 %
}

// Repeated exposures are averaged only if they agree in size and pixel format; otherwise the
// error names the odd exposure and the scene's first frame.
TEST(PipelineErrorsTest, MismatchedExposureNamesTheFiles) {
  sim::SimOptions o;
  ASSERT_EQ(o.step1.exposures, 3);
  const sim::RigSimulator simulator(o);
  const dataset::Recording rec = simulator.MakeRecording(/*with_hall=*/false);
  ASSERT_EQ(rec.step1[1].pose, rec.step1[0].pose);
  const std::string odd = rec.step1[1].file;
  const ImageLoader load = [&](const std::string& file) -> cv::Mat {
    return cv::Mat1b(file == odd ? 40 : 50, 60, uchar{0});
  };
  try {
    SolveRecording(rec, load);
    FAIL() << "expected SolveError";
  } catch (const SolveError& e) {
    EXPECT_NE(
        std::string(e.what()).find(odd + ": an exposure of the same scene as " + rec.step1[0].file),
        std::string::npos)
        << e.what();
  }
}

TEST(PipelineErrorsTest, UnreadableImageNamesTheFile) {
  sim::SimOptions o;
  const sim::RigSimulator simulator(o);
  const dataset::Recording rec = simulator.MakeRecording(/*with_hall=*/false);
  try {
    SolveRecording(rec, [](const std::string&) { return cv::Mat(); });
    FAIL() << "expected SolveError";
  } catch (const SolveError& e) {
    EXPECT_NE(std::string(e.what()).find(rec.step1[0].file + ": cannot read the image"),
              std::string::npos)
        << e.what();
  }
}

TEST(PipelineErrorsTest, InvalidOptionsNameTheField) {
  PipelineOptions o;
  o.ransac_iterations = 0;
  EXPECT_NE(o.Validate().find("ransac_iterations = 0"), std::string::npos);
  EXPECT_THROW(SolveRecording(dataset::Recording{}, {}, o), SolveError);
  PipelineOptions p;
  p.partial_frame_group_residual_px = 0;
  EXPECT_NE(p.Validate().find("partial_frame_group_residual_px = 0"), std::string::npos);
  PipelineOptions d;
  d.dots.max_fit_shift_px = -1;
  EXPECT_NE(d.Validate().find("max_fit_shift_px = -1"), std::string::npos);
}

}  // namespace
}  // namespace msmcal::solver
