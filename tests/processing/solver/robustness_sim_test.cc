// Robustness of the solve on images it was not tuned to (issue 15): the project's renderer with
// its scene drawn at random across spot size and power, board scale, tilt, noise, blur,
// vignetting, colour balance, mono/BGR, 8/16 bit; a second image model (gamma, another PSF,
// JPEG compression, vignetting) applied on top; a scene shaped like an independent simulator's
// (1600 x 1200 BGR, 17 x 12 world board with ~15 px squares, 9 x 6 sliding board, small
// saturated spots); and spoiled frames, which the solve must survive and name.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>

#include "common/units.h"
#include "mocks/rig/rig_simulator.h"
#include "mocks/rig/sim_options.h"
#include "processing/solver/diagnostics.h"
#include "processing/solver/pipeline.h"
#include "processing/solver/stages/common.h"
#include "processing/solver/stages/exposures.h"
#include "processing/solver/stages/measure.h"
#include "tests/testing/bayer.h"
#include "tests/testing/cached_loader.h"
#include "tests/testing/independent_like_scene.h"

namespace msmcal::solver {
namespace {

// A smaller camera (same field of view) so that scenes render and solve fast.
void ScaleCamera(sim::SimOptions* o, double f) {
  o->camera.width = static_cast<int>(std::lround(o->camera.width * f));
  o->camera.height = static_cast<int>(std::lround(o->camera.height * f));
  o->camera.fx *= f;
  o->camera.fy *= f;
  o->camera.cx = 0.5 * (o->camera.width - 1);
  o->camera.cy = 0.5 * (o->camera.height - 1);
}

using msmcal::testing::IndependentLikeScene;

struct SolveRun {
  std::unique_ptr<sim::RigSimulator> sim;
  dataset::Recording rec;
  SolveOutput out;
  std::string error;
};

// MSMCAL_TEST_DUMP=DIR: the images as the solver sees them and the simulator's settings
// (`msmcal simulate X --config DIR/sim.yaml` then gives their session.yaml), for
// `msmcal solve --explain` on a failing scene.
void MaybeDump(const sim::SimOptions& o, const std::string& file, const cv::Mat& img) {
  const char* dump = std::getenv("MSMCAL_TEST_DUMP");
  if (!dump || img.empty()) return;
  std::filesystem::create_directories((std::filesystem::path(dump) / file).parent_path());
  cv::imwrite((std::filesystem::path(dump) / file).string(), img);
  std::ofstream(std::filesystem::path(dump) / "sim.yaml") << sim::SimOptionsToYaml(o);
}

using ImageEdit = std::function<cv::Mat(const std::string& file, cv::Mat img)>;

SolveRun Solve(const sim::SimOptions& o, const ImageEdit& edit = {},
               const PipelineOptions& p = {}) {
  SolveRun r;
  r.sim = std::make_unique<sim::RigSimulator>(o);
  r.rec = r.sim->MakeRecording(/*with_hall=*/false);
  const ImageLoader load = msmcal::testing::CachedLoader([&](const std::string& file) -> cv::Mat {
    cv::Mat img;
    for (size_t i = 0; i < r.rec.step1.size(); ++i)
      if (r.rec.step1[i].file == file) img = r.sim->RenderStep1Frame(i);
    for (size_t i = 0; i < r.rec.step2.size(); ++i)
      if (r.rec.step2[i].file == file) img = r.sim->RenderStep2Frame(i);
    if (!img.empty() && edit) img = edit(file, img);
    MaybeDump(o, file, img);
    return img;
  });
  try {
    r.out = SolveRecording(r.rec, load, p);
  } catch (const SolveError& e) {
    r.error = e.what();
  }
  return r;
}

struct Errors {
  double normal_rms_deg = 0;
  double beam_max_deg = 0;
};

Errors AgainstTruth(const SolveRun& r) {
  Errors e;
  double s2 = 0;
  for (const auto& pl : r.out.planes) {
    const geometry::Plane truth =
        r.sim->MirrorPlaneInWorld(r.sim->triggers()[pl.j].t_s, sim::DriveMode::kScan);
    const double a = geometry::AngleBetween(pl.plane_in_world.n, truth.n) * common::kDegPerRad;
    s2 += a * a;
  }
  e.normal_rms_deg = std::sqrt(s2 / std::max<size_t>(1, r.out.planes.size()));
  for (const auto& b : r.out.beams) {
    const auto& truth = r.sim->beams_in_world()[b.beam - 1];
    e.beam_max_deg =
        std::max(e.beam_max_deg, geometry::AngleBetween(b.v, truth.v) * common::kDegPerRad);
  }
  return e;
}

// Where the error comes from: each shared parameter against the simulator's truth, with its
// predicted 1-sigma (printed; MSMCAL_TEST_DIAG=1).
void PrintDiagnosis(const SolveRun& r) {
  if (!std::getenv("MSMCAL_TEST_DIAG")) return;
  const Estimate& est = r.out.mle.estimate;
  const MleResult& m = r.out.mle;
  auto rot_err = [](const geometry::Rigid3d& a, const geometry::Rigid3d& b) {
    return Eigen::AngleAxisd(a.rotation * b.rotation.inverse()).angle() * common::kDegPerRad;
  };
  auto sig = [&](int off) {
    if (m.other_cov.rows() < off + 3) return 0.0;
    return std::sqrt(m.other_cov.block(off, off, 3, 3).trace()) * common::kDegPerRad;
  };
  std::printf(
      "  c1_from_world: rot err %.4f deg (sigma %.4f), t err %.3f mm\n",
      rot_err(est.c1_from_world, r.sim->c1_from_world()), sig(0),
      (est.c1_from_world.Inverse().translation - r.sim->c1_from_world().Inverse().translation)
          .norm());
  std::printf(
      "  c2_from_world: rot err %.4f deg (sigma %.4f), t err %.3f mm\n",
      rot_err(est.c2_from_world, r.sim->c2_from_world()), sig(6),
      (est.c2_from_world.Inverse().translation - r.sim->c2_from_world().Inverse().translation)
          .norm());
  for (size_t l = 0; l < est.c1_from_sliding.size() && l < r.sim->world_from_sliding().size();
       ++l) {
    const geometry::Rigid3d ws = est.c1_from_world.Inverse() * est.c1_from_sliding[l];
    std::printf("  sliding %zu: world rot err %.4f deg, c1 rot err %.4f deg\n", l,
                rot_err(ws, r.sim->world_from_sliding()[l]),
                rot_err(est.c1_from_sliding[l], r.sim->c1_from_sliding(static_cast<int>(l))));
  }
  for (size_t b = 0; b < est.beams.size(); ++b) {
    const auto& truth = r.sim->beams_in_world()[b];
    const int off = m.OffsetBeam(static_cast<int>(b));
    double s = 0;
    if (m.other_cov.rows() >= off + 4) s = std::sqrt(m.other_cov.block(off, off, 2, 2).trace());
    std::printf("  beam %zu: dir err %.4f deg (chart sigma %.5f)\n", b + 1,
                geometry::AngleBetween(est.beams[b].v, truth.v) * common::kDegPerRad,
                s * common::kDegPerRad);
  }
  for (const auto& pl : r.out.planes) {
    const geometry::Plane truth =
        r.sim->MirrorPlaneInWorld(r.sim->triggers()[pl.j].t_s, sim::DriveMode::kScan);
    const Eigen::Vector3d dn = pl.plane_in_world.n - truth.n;
    std::printf("  plane %d: err %.4f deg, dn (%.2e %.2e %.2e)\n", pl.j,
                geometry::AngleBetween(pl.plane_in_world.n, truth.n) * common::kDegPerRad, dn.x(),
                dn.y(), dn.z());
  }
  // Dot centres against the truth's projections (nearest measured dot within 3 px).
  std::map<std::string, const FrameDetection*> by_file;
  for (const auto& d : r.out.detections) by_file[d.file] = &d;
  auto match = [](const FrameDetection& d, const Eigen::Vector2d& t, Eigen::Vector2d* e) {
    double best = 3.0;
    for (const auto& p : d.dots_px)
      if ((p - t).norm() < best) best = (p - t).norm(), *e = p - t;
    return best < 3.0;
  };
  for (int step = 1; step <= 2; ++step) {
    double s2 = 0;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    int n = 0, missing = 0;
    std::vector<double> errs;
    auto add = [&](const FrameDetection& d, const std::optional<Eigen::Vector2d>& t) {
      if (!t) return;
      Eigen::Vector2d e = Eigen::Vector2d::Zero();
      if (!match(d, *t, &e)) return void(++missing);
      s2 += e.squaredNorm(), mean += e, ++n, errs.push_back(e.norm());
      if (e.norm() > 0.3)
        std::printf("    %s: dot at (%.1f %.1f) off (%.3f %.3f)\n", d.file.c_str(), t->x() + e.x(),
                    t->y() + e.y(), e.x(), e.y());
    };
    if (step == 1)
      for (const auto& f : r.rec.step1) {
        if (!by_file.count(f.file)) continue;
        for (int b : f.beams)
          add(*by_file.at(f.file),
              PredictSlidingDot(r.sim->camera(), r.sim->c1_from_world(),
                                r.sim->c1_from_sliding(f.pose), r.sim->beams_in_world()[b - 1]));
      }
    else
      for (const auto& f : r.rec.step2) {
        if (f.kind != dataset::Step2Kind::kScan || !by_file.count(f.file)) continue;
        for (int j : f.triggers)
          for (int b : f.beams)
            add(*by_file.at(f.file),
                PredictReflectedDot(
                    r.sim->camera(), r.sim->c2_from_world(), r.sim->beams_in_world()[b - 1],
                    r.sim->MirrorPlaneInWorld(r.sim->triggers()[j].t_s, sim::DriveMode::kScan)));
      }
    std::sort(errs.begin(), errs.end());
    std::printf("  step %d dots: %d matched, %d missing, RMS %.4f px, mean (%.4f %.4f), p90 %.4f\n",
                step, n, missing, std::sqrt(s2 / std::max(1, n)), mean.x() / std::max(1, n),
                mean.y() / std::max(1, n), errs.empty() ? 0.0 : errs[errs.size() * 9 / 10]);
  }
  // Corners against the truth's projections: RMS, mean, and the mean radial component (scale).
  auto corner_stats = [&](const std::string& name, const std::vector<Eigen::Vector2d>& det,
                          const std::vector<Eigen::Vector3d>& pts, const geometry::Rigid3d& pose) {
    if (det.size() != pts.size()) return;
    double worst = 0;
    size_t worst_i = 0;
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    for (const auto& d : det) c += d;
    c /= det.size();
    double s2 = 0, radial = 0, rr = 0;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (size_t i = 0; i < det.size(); ++i) {
      const auto t = r.sim->camera().Project(pose * pts[i]);
      if (!t) return;
      const Eigen::Vector2d e = det[i] - *t;
      if (e.norm() > worst) worst = e.norm(), worst_i = i;
      s2 += e.squaredNorm(), mean += e;
      const Eigen::Vector2d u = (*t - c);
      radial += e.dot(u.normalized()), rr += u.norm();
    }
    std::printf(
        "  %s corners: RMS %.4f px, mean (%.4f %.4f), mean radial %.4f px (mean r %.0f px), "
        "worst %.3f px at corner %zu (%.0f %.0f)\n",
        name.c_str(), std::sqrt(s2 / det.size()), mean.x() / det.size(), mean.y() / det.size(),
        radial / det.size(), rr / det.size(), worst, worst_i, det[worst_i].x(), det[worst_i].y());
  };
  for (size_t i = 0; i < r.rec.step1.size() && i < 40; i += 3) {
    const auto& f = r.rec.step1[i];
    if (!by_file.count(f.file)) continue;
    const auto& d = *by_file.at(f.file);
    for (const auto& b : d.boards) {
      if (!b.found) continue;
      if (b.name == "world")
        corner_stats("step1 world (" + b.method + ") " + f.file, b.corners_px,
                     BoardPoints(r.rec.world_board), r.sim->c1_from_world());
      else
        corner_stats("step1 sliding (" + b.method + ") " + f.file, b.corners_px,
                     BoardPoints(r.rec.sliding_board), r.sim->c1_from_sliding(f.pose));
    }
  }
  // Beam points: the truth's dot on each sliding pose carried through the estimated plate pose,
  // the error perpendicular to the beam (mm).
  for (size_t l = 0; l < est.c1_from_sliding.size() && l < r.sim->world_from_sliding().size();
       ++l) {
    const geometry::Rigid3d ws = est.c1_from_world.Inverse() * est.c1_from_sliding[l];
    std::printf("  pose %zu:", l);
    for (size_t b = 0; b < r.sim->beams_in_world().size(); ++b) {
      const auto x = r.sim->SlidingDotInWorld(static_cast<int>(b) + 1, static_cast<int>(l));
      if (!x) continue;
      const Eigen::Vector3d e = ws * (r.sim->world_from_sliding()[l].Inverse() * *x) - *x;
      const Eigen::Vector3d v = r.sim->beams_in_world()[b].v.normalized();
      const Eigen::Vector3d perp = e - e.dot(v) * v;
      std::printf(" b%zu perp (%.4f %.4f %.4f) along %.3f;", b + 1, perp.x(), perp.y(), perp.z(),
                  e.dot(v));
    }
    std::printf(" dist to c1 %.0f mm\n",
                (r.sim->c1_from_sliding(static_cast<int>(l)).translation).norm());
  }
  for (int f = 0; f < kNumFamilies; ++f)
    std::printf("  family %d: variance factor %.2f, redundancy %.1f\n", f, m.variance_factor[f],
                m.redundancy[f]);
}

// The run's figures against truth, printed under `label` (with the diagnosis when
// MSMCAL_TEST_DIAG=1).
Errors Report(const std::string& label, const SolveRun& r) {
  const Errors e = AgainstTruth(r);
  std::printf(
      "%s: %d scan planes, normal RMS %.4f deg, worst beam %.4f deg, normalised validation "
      "%.2f, dropped %zu\n",
      label.c_str(), r.out.num_scan_planes, e.normal_rms_deg, e.beam_max_deg,
      r.out.rms_normalised_validation, r.out.dropped.size());
  PrintDiagnosis(r);
  return e;
}

// The solve's note on a camera's response (RefineDotsOnBackgrounds): "camera response (step 1):
// median fitted gamma ... linear, ..." or "... not linear, ..."; empty when it made none.
std::string ResponseNote(const SolveRun& r, const std::string& step) {
  for (const auto& n : r.out.notes)
    if (n.rfind("camera response (" + step + ")", 0) == 0) return n;
  return "";
}
bool SaysLinear(const std::string& note) { return note.find(": linear,") != std::string::npos; }

// ------------------------------------------------------------------ a second image model
// Applied to the renderer's output: a gamma curve (sensor response), a box PSF on top of the
// renderer's Gaussian, radial vignetting, and JPEG-like compression (8x8 DCT quantisation).
cv::Mat OtherImageModel(const cv::Mat& img, double gamma, double vignette, int jpeg_quality,
                        bool box_blur = true) {
  cv::Mat f;
  img.convertTo(f, CV_32F, img.depth() == CV_16U ? 1.0 / 65535 : 1.0 / 255);
  if (box_blur) cv::blur(f, f, cv::Size(3, 3));
  const cv::Point2f c(0.5f * (f.cols - 1), 0.5f * (f.rows - 1));
  const float r2max = c.x * c.x + c.y * c.y;
  for (int y = 0; y < f.rows; ++y) {
    float* p = f.ptr<float>(y);
    for (int x = 0; x < f.cols; ++x) {
      const float r2 = ((x - c.x) * (x - c.x) + (y - c.y) * (y - c.y)) / r2max;
      const float g = 1.0f - static_cast<float>(vignette) * r2;
      for (int k = 0; k < f.channels(); ++k) {
        float& v = p[x * f.channels() + k];
        v = std::pow(std::clamp(v * g, 0.0f, 1.0f), static_cast<float>(gamma));
      }
    }
  }
  cv::Mat out;
  f.convertTo(out, CV_8U, 255.0);
  if (jpeg_quality > 100) return out;
  std::vector<uchar> jpeg;
  cv::imencode(".jpg", out, jpeg, {cv::IMWRITE_JPEG_QUALITY, jpeg_quality});
  return cv::imdecode(jpeg, cv::IMREAD_UNCHANGED);
}

TEST(RobustnessSimTest, IndependentLikeSceneSolves) {
  const SolveRun r = Solve(IndependentLikeScene(3));
  ASSERT_TRUE(r.error.empty()) << r.error;
  const Errors e = Report("independent-like", r);
  EXPECT_EQ(r.out.num_scan_planes, static_cast<int>(r.sim->triggers().size()));
  // Measured 0.018 deg / 0.023 deg with one exposure per step 1 frame (the goal is 0.010 deg;
  // cornerSubPix alone: 0.024 / 0.028). Over seeds 3-10 of this scene: plane-normal RMS
  // 0.004-0.022 deg, RMS over the seeds 0.014 deg, worst beam 0.008-0.023 deg (cornerSubPix
  // alone: 0.005-0.039 deg, RMS 0.021 deg).
  // MSMCAL_TEST_DIAG=1 shows where it comes from: the dots are within 0.011 px (step 1) and
  // 0.022 px (step 2) of truth, the corners within 0.02 px (the corner model; cornerSubPix: 0.04
  // px), the C1 and C2 world poses within 0.002-0.003 deg; the planes share one common offset
  // that follows the beams, whose points drift linearly over the sliding poses (the small
  // sliding board's depth from 54 corners of 16 px squares over ~70 mm of sliding). The beams'
  // own sigma is 0.015 deg: the error is honest noise of the step 1 board poses, not a bias.
  EXPECT_LT(e.normal_rms_deg, 0.025);
  EXPECT_LT(e.beam_max_deg, 0.03);
  EXPECT_LT(r.out.rms_normalised_validation, 2.0);
  // The renderer's response is linear, and the pooled gammas of both camera positions say so.
  EXPECT_TRUE(SaysLinear(ResponseNote(r, "step 1"))) << ResponseNote(r, "step 1");
  EXPECT_TRUE(SaysLinear(ResponseNote(r, "step 2"))) << ResponseNote(r, "step 2");
}

TEST(RobustnessSimTest, SecondImageModelSolves) {
  sim::SimOptions o = IndependentLikeScene(5);
  o.render.colour = false;
  const SolveRun r = Solve(o, [](const std::string&, cv::Mat img) {
    return OtherImageModel(img, /*gamma=*/0.6, /*vignette=*/0.35, /*jpeg_quality=*/85);
  });
  ASSERT_TRUE(r.error.empty()) << r.error;
  const Errors e = Report("second image model", r);
  // Measured: all 11 planes, 0.38 deg, beams 0.15 deg (session 11, before the corner model
  // fit: 0.33 / 0.14, within the beams' sigma of 0.15-0.37 deg; session 9: 0.42 / 0.20; before the
  // fit through the response: 0.47 deg; dots 0.60 px (step 2) and 0.43 px (step 1) off truth, now
  // 0.14 and 0.23 px). The dots' large errors were perpendicular to square edges: under the
  // gamma a spot adds less level on the light side (vision/dots.h, RefineDotOnBackground).
  // Session 10: the C1 world board's corners (variance factor ~10: cornerSubPix's 2 px window
  // on the slanted board's 10 px side, 0.6 px off truth) are now 0.04 px
  // (CheckerboardOptions::refine_window_min_px), and the JPEG ripple on clipped tops is read as
  // clipped (DotOptions::plateau_tolerance_fraction). What is left: the 3 x 3 filter applied
  // after the clip (MSMCAL_TEST_MODEL="1 0 101 1 0" in DISABLED_ImageModelParts: dots 0.16 /
  // 0.24 px), which spreads the clipped top into a ring of pixels that are neither clipped nor
  // the spot's level; the dots' variance factor (~25-130) says so, and the sigmas follow it.
  EXPECT_EQ(r.out.num_scan_planes, static_cast<int>(r.sim->triggers().size()));
  EXPECT_LT(e.normal_rms_deg, 0.5);
  EXPECT_LT(e.beam_max_deg, 0.25);
  // A gamma of 0.6: the pooled gammas see it.
  for (const std::string step : {"step 1", "step 2"}) {
    const std::string note = ResponseNote(r, step);
    EXPECT_FALSE(note.empty()) << step;
    EXPECT_FALSE(SaysLinear(note)) << note;
  }
}

// A lab's USB camera through V4L2 often delivers MJPEG: the issue 15 scene in mono, JPEG quality
// 85 and nothing else. Its clipped spots' tops are rippled by the compression; read as
// measurements they put the dots 0.3-0.4 px off truth and the planes 0.28 deg (before session
// 10); taken as clipped (vision::DotOptions::plateau_tolerance_fraction), 0.05-0.08 px.
// Session 12, with the corner model fit: 0.040 deg on this seed (0.022 with cornerSubPix
// alone; the beams' sigma is 0.03-0.04 deg, so both are single draws); over seeds 3-9 the
// planes' RMS is 0.042 deg against 0.048 deg with cornerSubPix alone.
TEST(RobustnessSimTest, JpegCompressedMonoSceneSolves) {
  sim::SimOptions o = IndependentLikeScene(5);
  o.render.colour = false;
  const SolveRun r = Solve(o, [](const std::string&, cv::Mat img) {
    return OtherImageModel(img, /*gamma=*/1.0, /*vignette=*/0.0, /*jpeg_quality=*/85,
                           /*box_blur=*/false);
  });
  ASSERT_TRUE(r.error.empty()) << r.error;
  const Errors e = Report("JPEG 85 mono", r);
  EXPECT_EQ(r.out.num_scan_planes, static_cast<int>(r.sim->triggers().size()));
  EXPECT_LT(e.normal_rms_deg, 0.08);
  EXPECT_LT(e.beam_max_deg, 0.08);
  EXPECT_LT(r.out.rms_normalised_validation, 2.0);
}

// A colour camera's BGR is not three sampled channels: the sensor has one colour filter per
// pixel (a Bayer mosaic, R G / G B or G R / B G) and the camera interpolates the other two. A
// saturated laser spot of sigma ~1.3 px then has half its green measured and half interpolated
// from neighbours that mix clipped and unclipped levels. Bilinear demosaicing (the cheapest,
// what many GigE cameras do on board) and OpenCV's edge-aware one, one per mosaic phase.
// Measured (seeds 3-5 x both phases x both methods, 12 runs): fitted over every pixel, dots
// 0.13-0.16 px off truth, plane normals 0.024-0.14 deg (RMS 0.088), worst beam up to 0.108
// deg; over the measured greens (dots.h, InterpolatedGreenParity), dots 0.03-0.04 px, normals
// 0.0085-0.076 deg (RMS 0.043), worst beam 0.040 deg. The planes' spread is a common offset per
// scene (the beams' and the sliding poses' noise, as in the three-channel scene, with half the
// green samples): here 0.017 deg (bilinear, R G / G B) and 0.076 deg (edge-aware, G R / B G);
// every pixel: 0.117 / 0.088 deg, beams 0.100 / 0.030 deg.
TEST(RobustnessSimTest, BayerDemosaicedColourCameraSolves) {
  for (bool edge_aware : {false, true}) {
    sim::SimOptions o = IndependentLikeScene(4);
    ASSERT_TRUE(o.render.colour);
    // Both phases of the mosaic: the edge-aware camera's green is measured where (x + y) is even.
    const int parity = edge_aware ? 1 : 0;
    const SolveRun r = Solve(o, [&](const std::string&, cv::Mat img) {
      return msmcal::testing::Demosaic(msmcal::testing::BayerMosaic(img, parity), parity,
                                       edge_aware);
    });
    ASSERT_TRUE(r.error.empty()) << r.error;
    const Errors e =
        Report(edge_aware ? "Bayer, edge-aware demosaic" : "Bayer, bilinear demosaic", r);
    EXPECT_EQ(r.out.num_scan_planes, static_cast<int>(r.sim->triggers().size()));
    EXPECT_LT(e.normal_rms_deg, edge_aware ? 0.1 : 0.04);
    EXPECT_LT(e.beam_max_deg, 0.05);
    EXPECT_LT(r.out.rms_normalised_validation, 2.0);
  }
}

// Which part of the second image model costs the accuracy: MSMCAL_TEST_MODEL="gamma vignette
// jpeg_quality(>100: none) box_blur(0/1) colour(0/1)", run by hand with
// --gtest_also_run_disabled_tests.
TEST(RobustnessSimTest, DISABLED_ImageModelParts) {
  const char* spec = std::getenv("MSMCAL_TEST_MODEL");
  double gamma = 0.6, vignette = 0.35;
  int jpeg = 85, blur = 1, colour = 0;
  if (spec) std::sscanf(spec, "%lf %lf %d %d %d", &gamma, &vignette, &jpeg, &blur, &colour);
  sim::SimOptions o = IndependentLikeScene(5);
  o.render.colour = colour != 0;
  const SolveRun r = Solve(o, [&](const std::string&, cv::Mat img) {
    return OtherImageModel(img, gamma, vignette, jpeg, blur != 0);
  });
  ASSERT_TRUE(r.error.empty()) << r.error;
  char label[120];
  std::snprintf(label, sizeof(label), "model gamma %.2f vignette %.2f jpeg %d blur %d colour %d",
                gamma, vignette, jpeg, blur, colour);
  Report(label, r);
}

// random_scenes.py seed 128 (its sim.yaml): dim small spots (peak 0.3 of full scale, 4-6 px
// above the first pass's threshold) on a 21 x 14 board of 21 px squares, 3 triggers per scan
// frame. The first pass refuses every spot as too small; the data-driven second pass on a
// whole step 2 image finds the spots and board texture with them (the neutral frames 11 blobs
// for 3 dots, the 2-trigger scan frame 18 for 6). Left to the grouping, those surplus blobs gave
// a wrong neutral plane and the solve failed ("trigger assignment failed: 12 of 17 mirror planes
// ... fit no drive-phase model"). A surplus is now measured again on the frame's difference
// from its static scene, as a shortfall is: exactly the expected dots, and the solve succeeds
// (session 23: normals 0.089 deg RMS against truth, within {0}'s rotation sigma of 0.24-0.26
// deg, validation normalised 1.12; 0.072 deg and 0.50 with the step 1 rule of the next test).
TEST(RobustnessSimTest, DimSmallSpotsWithBoardTextureSurplusSolve) {
  const sim::SimOptions options = sim::ParseSimOptions(R"(seed: 128
mirror:
  slow:
    amplitude_vpp: 4
geometry:
  board_aim_mm: [113.4, 75.6]
  mirror_distance_mm: 250
beams:
  spanning_angle_deg: 19.8
world_board:
  cols: 21
  rows: 14
  square_mm: 12
sliding_board:
  cols: 11
  rows: 6
  square_mm: 10
camera:
  width: 1280
  height: 1024
  fx: 947.5
  fy: 946.5
  cx: 646.2
  cy: 520.0
  distortion: [-0.144, 0.033, 0, 0, 0]
  c1_centre_mm: [-606, 76, -531]
  c1_target_mm: [60, 76, -150]
  c2_centre_mm: [193, 84, -521]
  c2_target_mm: [113, 76, 0]
render:
  dot_sigma_mm: 0.36
  dot_peak: 0.3
  noise_sigma: 0.0022
  colour: false
step1:
  exposures: 1
step2:
  scan_triggers_per_frame: 3
)",
                                                       "random_scenes seed 128");
  const SolveRun r = Solve(options);
  ASSERT_TRUE(r.error.empty()) << r.error;
  const Errors e = Report("seed 128", r);
  int step2_frames = 0;
  for (const auto& d : r.out.detections) {
    if (d.step != "step2") continue;
    ++step2_frames;
    EXPECT_TRUE(d.used) << d.file << ": " << d.reason;
    EXPECT_EQ(d.dots_found, d.dots_expected) << d.file << ": " << d.note;
  }
  EXPECT_EQ(step2_frames, 11);
  EXPECT_EQ(r.out.num_scan_planes, static_cast<int>(r.sim->triggers().size()));
  EXPECT_LT(e.normal_rms_deg, 0.2);
  EXPECT_LT(r.out.rms_normalised_validation, 2.0);
}

// random_scenes.py seed 158: small dim spots (peak 0.3) in noise sigma 0.009 on a sliding board
// of ~12 px squares. The first pass takes board texture for spots: the background frames of 4
// of the 7 sliding poses (every beam blocked) show 2-3 blobs on the plate, and a frame of those
// poses whose one expected dot was matched by one blob may hold texture instead of its spot. In
// such a pose every frame is measured on its difference from the pose's other images too (kept
// where it comes at least as close to the expected count), and step 1 labels 22 of the 24
// listed dots (19 before; normals 0.116 -> 0.114 deg, validation normalised 1.55 -> 1.43).
TEST(RobustnessSimTest, PosesWhoseBackgroundShowsBlobsAreMeasuredOnTheirDifference) {
  const sim::SimOptions options = sim::ParseSimOptions(R"(seed: 158
mirror:
  slow:
    amplitude_vpp: 4
geometry:
  board_aim_mm: [113.4, 75.6]
  mirror_distance_mm: 230
beams:
  spanning_angle_deg: 25.2
world_board:
  cols: 21
  rows: 14
  square_mm: 12
sliding_board:
  cols: 11
  rows: 8
  square_mm: 8
camera:
  width: 1600
  height: 1200
  fx: 1320.9
  fy: 1321.6
  cx: 782.1
  cy: 584.1
  distortion: [0.004, 0.034, 0, 0, 0]
  c1_centre_mm: [-676, 76, -592]
  c1_target_mm: [60, 76, -150]
  c2_centre_mm: [193, 84, -581]
  c2_target_mm: [113, 76, 0]
render:
  dot_sigma_mm: 0.34
  dot_peak: 0.3
  noise_sigma: 0.0089
  colour: false
step1:
  exposures: 1
step2:
  scan_triggers_per_frame: 1
)",
                                                       "random_scenes seed 158");
  const SolveRun r = Solve(options);
  ASSERT_TRUE(r.error.empty()) << r.error;
  Report("seed 158", r);
  ASSERT_GE(r.out.detections.size(), r.rec.step1.size());
  std::set<int> texture_poses;
  for (size_t i = 0; i < r.rec.step1.size(); ++i)
    if (r.out.detections[i].dots_expected == 0 && r.out.detections[i].dots_found > 0)
      texture_poses.insert(r.rec.step1[i].pose);
  EXPECT_GE(texture_poses.size(), 2u);
  int measured_on_difference = 0;
  for (size_t i = 0; i < r.rec.step1.size(); ++i) {
    const auto& d = r.out.detections[i];
    if (!texture_poses.count(r.rec.step1[i].pose) || d.dots_expected == 0) continue;
    EXPECT_NE(d.note.find("difference from its static scene"), std::string::npos) << d.file;
    EXPECT_EQ(d.dots_found, d.dots_expected) << d.file;
    ++measured_on_difference;
  }
  EXPECT_GE(measured_on_difference, 6);
  int labelled = -1;
  for (const auto& n : r.out.notes)
    if (n.rfind("step 1: dot-to-beam labels", 0) == 0)
      labelled = std::atoi(n.substr(n.rfind('(') + 1).c_str());
  EXPECT_GE(labelled, 22);
}

// ------------------------------------------------------------------ spoiled frames
TEST(RobustnessSimTest, SpoiledFramesAreNamedWithTheirReason) {
  sim::SimOptions o;
  o.seed = 7;
  ScaleCamera(&o, 0.5);
  o.step1.exposures = 1;
  const sim::RigSimulator plan(o);
  const dataset::Recording rec = plan.MakeRecording(/*with_hall=*/false);
  // A step 1 frame with every beam (not an identification frame), a scan frame, a fast-only frame.
  std::string black, blurred, half;
  for (const auto& f : rec.step1)
    if (black.empty() && f.beams.size() > 1) black = f.file;
  for (const auto& f : rec.step2) {
    if (blurred.empty() && f.kind == dataset::Step2Kind::kScan) blurred = f.file;
    if (half.empty() && f.kind == dataset::Step2Kind::kFastOnly) half = f.file;
  }
  ASSERT_FALSE(black.empty() || blurred.empty() || half.empty());
  const SolveRun r = Solve(o, [&](const std::string& file, cv::Mat img) -> cv::Mat {
    if (file == black) return cv::Mat::zeros(img.size(), img.type());
    if (file == blurred) {
      cv::GaussianBlur(img, img, cv::Size(0, 0), 12.0);
      return img;
    }
    if (file == half) {  // the board half out of view: the image shifted by half its width
      cv::Mat out = cv::Mat::zeros(img.size(), img.type());
      img(cv::Rect(img.cols / 2, 0, img.cols - img.cols / 2, img.rows))
          .copyTo(out(cv::Rect(0, 0, img.cols - img.cols / 2, img.rows)));
      return out;
    }
    return img;
  });
  ASSERT_TRUE(r.error.empty()) << r.error;
  ASSERT_EQ(r.out.detections.size(), rec.step1.size() + rec.step2.size());
  std::map<std::string, const FrameDetection*> by_file;
  for (const auto& d : r.out.detections) by_file[d.file] = &d;
  for (const std::string& f : {black, blurred, half}) {
    const FrameDetection& d = *by_file.at(f);
    std::printf("%s: used %d, reason '%s'\n", f.c_str(), d.used, d.reason.c_str());
    EXPECT_FALSE(d.used) << f;
    EXPECT_FALSE(d.reason.empty()) << f;
  }
  EXPECT_NE(by_file.at(black)->reason.find("not found"), std::string::npos);
  EXPECT_NE(by_file.at(half)->reason.find("world board"), std::string::npos);
  // Every other frame is used, and its row says how its boards were found.
  int used = 0;
  for (const auto& d : r.out.detections) {
    if (d.file == black || d.file == blurred || d.file == half) continue;
    used += d.used;
    if (d.used) {
      EXPECT_TRUE(d.boards[0].found || d.partial) << d.file;
    }
  }
  EXPECT_GE(used, static_cast<int>(r.out.detections.size()) - 3 - 2);
  // The CSV: the contract's first columns, one row per frame, the spoiled ones with used = 0.
  const std::string csv = FormatDetectionsCsv(r.out.detections);
  EXPECT_EQ(csv.rfind("file,step,used,reason,", 0), 0u);
  EXPECT_EQ(static_cast<size_t>(std::count(csv.begin(), csv.end(), '\n')),
            r.out.detections.size() + 1);
  EXPECT_NE(csv.find(black + ",step1,0,"), std::string::npos);
  const DropSummary sum = SummariseDrops(r.out.detections);
  EXPECT_GE(sum.dropped, 3);
  EXPECT_FALSE(sum.hint.empty());
  // The annotated image is the frame's size, 8-bit BGR.
  const cv::Mat annotated = AnnotateFrame(cv::Mat::zeros(100, 120, CV_16UC1), *by_file.at(black));
  EXPECT_EQ(annotated.type(), CV_8UC3);
  EXPECT_EQ(annotated.size(), cv::Size(120, 100));
}

// A solve that fails still says which frames it measured and why it dropped them.
TEST(RobustnessSimTest, FailedSolveCarriesItsDetections) {
  sim::SimOptions o;
  o.seed = 8;
  ScaleCamera(&o, 0.5);
  o.step1.exposures = 1;
  sim::RigSimulator s(o);
  const dataset::Recording rec = s.MakeRecording(/*with_hall=*/false);
  const ImageLoader black = [&](const std::string&) {
    return cv::Mat(cv::Size(o.camera.width, o.camera.height), CV_8UC1, cv::Scalar(0));
  };
  try {
    SolveRecording(rec, black);
    FAIL() << "expected a SolveError";
  } catch (const SolveError& e) {
    ASSERT_TRUE(e.partial);
    ASSERT_EQ(e.partial->detections.size(), rec.step1.size() + rec.step2.size());
    for (const auto& d : e.partial->detections) {
      EXPECT_FALSE(d.used);
      EXPECT_FALSE(d.reason.empty());
    }
    const DropSummary sum = SummariseDrops(e.partial->detections);
    EXPECT_NE(sum.hint.find("board was not found"), std::string::npos) << sum.hint;
  }
}

// ------------------------------------------------------------------ randomised suite
// Scenes drawn across what a lab's images vary in; each solves, and its normalised validation
// error stays honest.
struct Draw {
  sim::SimOptions sim;
  double gain = 1, offset = 0;              // albedo / exposure: level' = gain * level + offset
  double vignette = 0;                      // relative fall-off at the corners
  double blur_px = 0;                       // extra defocus
  std::array<double, 3> bgr_gain{1, 1, 1};  // colour balance
  bool sixteen_bit = false;
  std::string text;
};

Draw DrawScene(int k) {
  std::mt19937_64 rng(1000 + k);
  auto u = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  Draw d;
  sim::SimOptions& o = d.sim;
  o.seed = 100 + k;
  const double scale = u(0.4, 0.6);
  ScaleCamera(&o, scale);
  o.step1.exposures = 1;
  o.step1.poses = 5;  // mechanics of detection, not accuracy: fewer frames
  o.triggers.max_triggers = 24;
  o.render.dot_sigma_mm = u(0.35, 0.9);
  o.render.dot_peak = u(0.35, 2.0);
  o.render.noise_sigma = u(0.002, 0.012);
  o.render.colour = rng() % 2 == 0;
  o.step1.tilt_deg = u(0, 25);
  o.beams.spanning_angle_deg = u(18, 46);
  // Exposure as a lab sets it: the light squares (0.8 of full scale in the renderer) stay below
  // clipping in every channel (a clipped board hides the spots on it from any detector).
  d.gain = u(0.7, 1.1);
  d.offset = u(-0.02, 0.04);
  d.vignette = u(0, 0.4);
  d.blur_px = u(0, 1.0);
  if (o.render.colour) d.bgr_gain = {u(0.75, 1.15), u(0.85, 1.15), u(0.75, 1.15)};
  double brightest_gain = d.gain;
  if (o.render.colour) brightest_gain *= *std::max_element(d.bgr_gain.begin(), d.bgr_gain.end());
  if (0.8 * brightest_gain + d.offset > 0.95) d.gain *= (0.95 - d.offset) / (0.8 * brightest_gain);
  d.sixteen_bit = rng() % 3 == 0;
  char buf[300];
  std::snprintf(buf, sizeof(buf),
                "scene %d: scale %.2f, spot %.2f mm peak %.2f, noise %.3f, %s %d-bit, tilt %.0f, "
                "span %.0f, gain %.2f offset %.2f, vignette %.2f, blur %.2f",
                k, scale, o.render.dot_sigma_mm, o.render.dot_peak, o.render.noise_sigma,
                o.render.colour ? "BGR" : "mono", d.sixteen_bit ? 16 : 8, o.step1.tilt_deg,
                o.beams.spanning_angle_deg, d.gain, d.offset, d.vignette, d.blur_px);
  d.text = buf;
  return d;
}

cv::Mat ApplyDraw(const Draw& d, const cv::Mat& img) {
  cv::Mat f;
  img.convertTo(f, CV_32F, 1.0 / 255);
  if (d.blur_px > 0.05) cv::GaussianBlur(f, f, cv::Size(0, 0), d.blur_px);
  const cv::Point2f c(0.5f * (f.cols - 1), 0.5f * (f.rows - 1));
  const float r2max = c.x * c.x + c.y * c.y;
  const int ch = f.channels();
  for (int y = 0; y < f.rows; ++y) {
    float* p = f.ptr<float>(y);
    for (int x = 0; x < f.cols; ++x) {
      const float r2 = ((x - c.x) * (x - c.x) + (y - c.y) * (y - c.y)) / r2max;
      const float g = static_cast<float>(d.gain * (1.0 - d.vignette * r2));
      for (int k = 0; k < ch; ++k) {
        float& v = p[x * ch + k];
        v = v * g * static_cast<float>(ch == 3 ? d.bgr_gain[k] : 1.0) +
            static_cast<float>(d.offset);
      }
    }
  }
  cv::Mat out;
  if (d.sixteen_bit)
    f.convertTo(out, CV_MAKETYPE(CV_16U, ch), 65535.0);
  else
    f.convertTo(out, CV_MAKETYPE(CV_8U, ch), 255.0);
  return out;
}

class RandomisedScenes : public ::testing::TestWithParam<int> {};

// Today not every scene solves (see the README's "Images the solver has been shown to handle"):
// a scene may fail, but only with a SolveError that names what failed and keeps its per-frame
// detections (never a crash or a bare exception); a scene that solves has honest normalised
// errors and planes in the right place. The printed lines are the suite's figures.
TEST_P(RandomisedScenes, SolvesHonestlyOrSaysWhy) {
  const Draw d = DrawScene(GetParam());
  std::printf("%s\n", d.text.c_str());
  SolveRun r;
  r.sim = std::make_unique<sim::RigSimulator>(d.sim);
  r.rec = r.sim->MakeRecording(/*with_hall=*/false);
  const ImageLoader load = msmcal::testing::CachedLoader([&](const std::string& file) -> cv::Mat {
    cv::Mat img;
    for (size_t i = 0; i < r.rec.step1.size(); ++i)
      if (r.rec.step1[i].file == file) img = ApplyDraw(d, r.sim->RenderStep1Frame(i));
    for (size_t i = 0; i < r.rec.step2.size(); ++i)
      if (r.rec.step2[i].file == file) img = ApplyDraw(d, r.sim->RenderStep2Frame(i));
    MaybeDump(d.sim, file, img);
    return img;
  });
  try {
    PipelineOptions p;
    r.out = SolveRecording(r.rec, load, p);
  } catch (const SolveError& e) {
    std::printf("  NOT SOLVED: %.300s\n", e.what());
    ASSERT_TRUE(e.partial) << "a failed solve carries its detections";
    EXPECT_EQ(e.partial->detections.size(), r.rec.step1.size() + r.rec.step2.size());
    const DropSummary sum = SummariseDrops(e.partial->detections);
    std::printf("  hint: %s\n", sum.hint.c_str());
    EXPECT_FALSE(sum.hint.empty());
    return;
  }
  const Errors e = AgainstTruth(r);
  std::printf(
      "  SOLVED: %d of %zu scan planes, normal RMS %.4f deg, worst beam %.4f deg, "
      "normalised validation %.2f, dropped %zu\n",
      r.out.num_scan_planes, r.sim->triggers().size(), e.normal_rms_deg, e.beam_max_deg,
      r.out.rms_normalised_validation, r.out.dropped.size());
  for (const auto& dr : r.out.dropped)
    std::printf("  dropped %s: %s\n", dr.file.c_str(), dr.reason.c_str());
  for (const auto& n : r.out.notes) std::printf("  note: %s\n", n.c_str());
  // Honest: the held-out beam's errors against their predicted covariance (1 expected; one
  // scene's RMS over ~20 dots scatters by about +-30 %).
  EXPECT_LT(r.out.rms_normalised_validation, 2.5) << d.text;
  // A scene whose planes are far off while its held-out dots agree would be planes attached to
  // the wrong trigger times (the validation cannot see that; scene 15 did this until the
  // drive-phase model was refined on its inliers only).
  EXPECT_LT(e.normal_rms_deg, 0.5) << d.text;
  // Beams named right: scene 7 once solved with beams 2 and 3 swapped (14 deg off truth) after
  // a blob in an identification frame bent one beam's line.
  EXPECT_LT(e.beam_max_deg, 0.5) << d.text;
}

INSTANTIATE_TEST_SUITE_P(Draws, RandomisedScenes, ::testing::Range(0, 40));

// Board hints (PipelineOptions::hint_boards_from_first_frame) change where the detectors look
// first, not what they find: on a scene whose world board SB finds only upscaled or on the
// board's checker-like region (vision::TexturedRegions; before those, only the 2x upscaled search)
// (scene 15: 17 px squares seen at a slant), every image's boards are found with hints as
// without, with the same corners (the refinement runs on the whole image either way), and the
// boards of the views' later images are found in their hint's region.
TEST(BoardHints, FindTheSameBoardsWhereTheFirstFrameOfTheViewHadThem) {
  const Draw d = DrawScene(15);
  const sim::RigSimulator simulator(d.sim);
  const dataset::Recording rec = simulator.MakeRecording(/*with_hall=*/false);
  const ImageLoader load = msmcal::testing::CachedLoader([&](const std::string& file) -> cv::Mat {
    for (size_t i = 0; i < rec.step1.size(); ++i)
      if (rec.step1[i].file == file) return ApplyDraw(d, simulator.RenderStep1Frame(i));
    for (size_t i = 0; i < rec.step2.size(); ++i)
      if (rec.step2[i].file == file) return ApplyDraw(d, simulator.RenderStep2Frame(i));
    return cv::Mat();
  });
  PipelineOptions with, without;
  without.hint_boards_from_first_frame = false;
  const RecordingMeasurement a = MeasureRecording(rec, load, with);
  const RecordingMeasurement b = MeasureRecording(rec, load, without);
  ASSERT_TRUE(a.log.error.empty()) << a.log.error;
  ASSERT_EQ(a.images.size(), b.images.size());
  int hinted = 0, costly = 0, boards = 0;
  double worst = 0;
  for (size_t i = 0; i < a.images.size(); ++i) {
    ASSERT_EQ(a.images[i].boards.size(), b.images[i].boards.size());
    for (size_t k = 0; k < a.images[i].boards.size(); ++k) {
      const auto& x = a.images[i].boards[k];
      const auto& y = b.images[i].boards[k];
      ASSERT_EQ(x.has_value(), y.has_value()) << a.detections[i].file << " board " << k;
      if (!x) continue;
      ++boards;
      EXPECT_FALSE(y->hinted);
      hinted += x->hinted;
      costly += y->method == vision::BoardMethod::kSbUpscaled ||
                b.images[i].board_attempts[k].back().textured;
      for (size_t c = 0; c < x->corners_px.size(); ++c)
        worst = std::max(worst, (x->corners_px[c] - y->corners_px[c]).norm());
    }
  }
  std::printf(
      "%d boards, %d found upscaled or on a checker-like region without hints, %d in a hint's "
      "region; "
      "corners differ by at most %.4f px\n",
      boards, costly, hinted, worst);
  EXPECT_GE(costly, 5) << "the scene no longer exercises the costly searches";
  // Every image but the two views' first: its world board in the region (the sliding board
  // moves between step 1 poses: its own hint may miss).
  EXPECT_GE(hinted, static_cast<int>(a.images.size()) - 2);
  // The refinement (cornerSubPix, then the corner model's fit) starts from where the detector
  // put the corner, and stops within its tolerances: measured 0.018 px at most, against corner
  // errors of 0.02-0.04 px RMS.
  EXPECT_LT(worst, 0.05);
}

// A view whose first image misses a board (step 1: the world board hidden in the first frame)
// takes that board's hint from the first image that found it: the next rounds (2, then 4, ...
// images) search unhinted for it, and every image after them finds it in the region.
TEST(BoardHints, AViewWhoseFirstFrameMissesABoardTakesItsHintFromALaterOne) {
  const Draw d = DrawScene(15);
  const sim::RigSimulator simulator(d.sim);
  const dataset::Recording rec = simulator.MakeRecording(/*with_hall=*/false);
  PipelineOptions o;
  // Where the world board is in step 1 (the camera and the world board do not move).
  const cv::Mat first = ApplyDraw(d, simulator.RenderStep1Frame(0));
  const ImageMeasurement plain = MeasureImage(first,
                                              {{rec.world_board.cols, rec.world_board.rows},
                                               {rec.sliding_board.cols, rec.sliding_board.rows}},
                                              o.dots, o.boards);
  ASSERT_TRUE(plain.boards[0].has_value());
  std::vector<cv::Point2f> corners;
  for (const auto& c : plain.boards[0]->corners_px) corners.emplace_back(c.x(), c.y());
  const cv::Rect world = cv::boundingRect(corners);
  const ImageLoader load = msmcal::testing::CachedLoader([&](const std::string& file) -> cv::Mat {
    for (size_t i = 0; i < rec.step1.size(); ++i) {
      if (rec.step1[i].file != file) continue;
      cv::Mat img = ApplyDraw(d, simulator.RenderStep1Frame(i));
      if (i == 0) {  // the world board covered by a grey card
        const cv::Rect card = (world + cv::Size(40, 40)) - cv::Point(20, 20);
        img(card & cv::Rect(0, 0, img.cols, img.rows)).setTo(cv::mean(img(world)));
      }
      return img;
    }
    for (size_t i = 0; i < rec.step2.size(); ++i)
      if (rec.step2[i].file == file) return ApplyDraw(d, simulator.RenderStep2Frame(i));
    return cv::Mat();
  });
  const RecordingMeasurement m = MeasureRecording(rec, load, o);
  ASSERT_TRUE(m.log.error.empty()) << m.log.error;
  ASSERT_GE(rec.step1.size(), 6u);
  EXPECT_FALSE(m.images[0].boards[0].has_value()) << "the card does not hide the world board";
  // Round 2 (frames 1 and 2) searched the whole image for the world board and found it.
  for (size_t i : {1u, 2u}) {
    ASSERT_TRUE(m.images[i].boards[0].has_value()) << m.detections[i].file;
    EXPECT_FALSE(m.images[i].boards[0]->hinted) << m.detections[i].file;
  }
  // Every later step 1 frame found it in frame 1's region.
  for (size_t i = 3; i < rec.step1.size(); ++i) {
    ASSERT_TRUE(m.images[i].boards[0].has_value()) << m.detections[i].file;
    EXPECT_TRUE(m.images[i].boards[0]->hinted) << m.detections[i].file;
  }
}

// random_scenes.py seed 113 (its sim.yaml): a 25 x 18 world board of 7-10 px squares seen at a
// slant in 1600 x 1200. The mean of the first step 1 scene's three exposures, as the solve
// measures it: SB finds nothing on the whole image (coarse, full resolution), nor on the board's
// checker-like region at x1 or x2; at x3 there it finds the board (before the whole-image x2
// search, which also fails), every corner within 0.25 px of the truth's
// projection. Before, no frame of that folder showed its world board and the solve failed.
TEST(CheckerboardRegions, ABoardOfSmallSquaresIsFoundOnItsRegionUpscaledThreeTimes) {
  const sim::SimOptions options = sim::ParseSimOptions(R"(seed: 113
mirror:
  slow:
    amplitude_vpp: 2
geometry:
  board_aim_mm: [112.5, 81.0]
  mirror_distance_mm: 200
beams:
  spanning_angle_deg: 28.5
world_board:
  cols: 25
  rows: 18
  square_mm: 10
sliding_board:
  cols: 7
  rows: 6
  square_mm: 12
camera:
  width: 1600
  height: 1200
  fx: 1349.6
  fy: 1348.6
  cx: 803.4
  cy: 599.3
  distortion: [-0.080, -0.008, 0, 0, 0]
  c1_centre_mm: [-691, 81, -605]
  c1_target_mm: [60, 81, -150]
  c2_centre_mm: [192, 89, -594]
  c2_target_mm: [112, 81, 0]
render:
  dot_sigma_mm: 0.69
  dot_peak: 2.0
  noise_sigma: 0.0036
  colour: false
step1:
  exposures: 3
step2:
  scan_triggers_per_frame: 1
)",
                                                       "random_scenes seed 113");
  const sim::RigSimulator simulator(options);
  const dataset::Recording rec = simulator.MakeRecording(/*with_hall=*/false);
  ASSERT_GE(rec.step1.size(), 3u);
  std::vector<std::string> scene;
  for (size_t i = 0; i < 3; ++i) {
    ASSERT_EQ(rec.step1[i].pose, rec.step1[0].pose);
    scene.push_back(rec.step1[i].file);
  }
  const cv::Mat mean = AverageExposures(scene, [&](const std::string& file) {
    for (size_t i = 0; i < 3; ++i)
      if (rec.step1[i].file == file) return simulator.RenderStep1Frame(i);
    return cv::Mat();
  });
  const vision::BoardSize world{rec.world_board.cols, rec.world_board.rows};
  std::vector<vision::BoardAttempt> attempts;
  const auto found = vision::DetectCheckerboard(mean, world, {}, cv::Mat(), &attempts);
  for (const auto& a : attempts)
    std::printf("  %s x%.1f %s%s: %s\n", vision::ToString(a.method), a.scale,
                a.region.empty() ? "whole image" : "region", a.textured ? " (checker-like)" : "",
                a.accepted ? "accepted" : "no");
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->method, vision::BoardMethod::kSbUpscaled);
  EXPECT_EQ(found->scale, 3.0);
  ASSERT_FALSE(attempts.empty());
  EXPECT_TRUE(attempts.back().textured);
  for (size_t k = 0; k + 1 < attempts.size(); ++k) EXPECT_FALSE(attempts[k].found);
  const auto pts = BoardPoints(rec.world_board);
  ASSERT_EQ(found->corners_px.size(), pts.size());
  double worst = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    const auto t = simulator.camera().Project(simulator.c1_from_world() * pts[i]);
    ASSERT_TRUE(t.has_value());
    worst = std::max(worst, (found->corners_px[i] - *t).norm());
  }
  std::printf("%zu corners, worst %.3f px from the truth\n", pts.size(), worst);
  EXPECT_LT(worst, 0.25);
}

}  // namespace
}  // namespace msmcal::solver
