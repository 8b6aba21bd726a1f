// Honest sigmas on rendered images (issue 6's acceptance check): over 8 simulated sessions
// (scene jittered per seed), the errors of the solved poses (alpha, beta, trans in {0}) against
// the simulator's truth in the same {0} convention, divided by their predicted sigmas, and the
// validation dots' normalised errors have unit RMS within +-25 %. Measured (the solve is
// reproducible, so these are exact): alpha 0.80, beta 1.16, trans 1.20, validation 0.85, with
// dots fitted over a background measured in the other images of their static scene
// (docs/solver.md, "Dots"). Before that fit: 1.60 / 1.38 / 1.38 / 1.10. Also prints the errors
// of the shared parameters (camera poses, beams) and of the planes that define {0}.
// MSMCAL_HONESTY_SEEDS=N runs N seeds (default 8).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>

#include "common/units.h"
#include "mocks/rig/rig_simulator.h"
#include "processing/geometry/mirror_frame.h"
#include "processing/solver/home_frame.h"
#include "processing/solver/mle.h"
#include "processing/solver/pipeline.h"
#include "tests/testing/cached_loader.h"

namespace msmcal::solver {
namespace {

struct Acc {
  double z2 = 0;
  int n = 0;
  void Add(double z) { z2 += z * z, ++n; }
  double Rms() const { return n ? std::sqrt(z2 / n) : 0; }
};

TEST(HonestySimTest, NormalisedErrorsHaveUnitRms) {
  int num_seeds = 8;
  if (const char* e = std::getenv("MSMCAL_HONESTY_SEEDS")) num_seeds = std::atoi(e);
  Acc za, zb, zt, zv, trans_err, zbeam, znormal;
  int skipped = 0;
  for (int seed = 1; seed <= num_seeds; ++seed) {
    sim::SimOptions o;
    o.seed = static_cast<uint64_t>(seed) + 10;
    // The simulator's geometry does not depend on the seed, and most of a dot's centroid error
    // is a bias fixed by where the spot lands on the board pattern: without moving the scene,
    // every seed would repeat one realisation of those biases. Jitter where the beams land.
    std::mt19937_64 rng(1000 + seed);
    std::uniform_real_distribution<double> aim(-5.0, 5.0), tilt(-0.5, 0.5);
    o.geometry.board_aim_mm[0] += aim(rng);
    o.geometry.board_aim_mm[1] += aim(rng);
    for (double& t : o.geometry.mount_tilt_deg) t += tilt(rng);
    const sim::RigSimulator simulator(o);
    const dataset::Recording rec = simulator.MakeRecording(/*with_hall=*/false);
    const ImageLoader load = msmcal::testing::CachedLoader([&](const std::string& file) -> cv::Mat {
      for (size_t i = 0; i < rec.step1.size(); ++i)
        if (rec.step1[i].file == file) return simulator.RenderStep1Frame(i);
      for (size_t i = 0; i < rec.step2.size(); ++i)
        if (rec.step2[i].file == file) return simulator.RenderStep2Frame(i);
      return cv::Mat();
    });
    SolveOutput out;
    try {
      out = SolveRecording(rec, load);
    } catch (const SolveError& e) {
      // A jittered scene can put a step 1 dot where the detector loses it; that is not what
      // this test measures.
      std::printf("seed %d skipped: %s\n", seed + 10, e.what());
      ++skipped;
      continue;
    }
    // Truth in the solver's {0} convention (home_frame.h), over the same trigger indices.
    std::vector<geometry::Plane> true_scan;
    for (const auto& row : out.planes)
      true_scan.push_back(
          simulator.MirrorPlaneInWorld(simulator.triggers()[row.j].t_s, sim::DriveMode::kScan));
    const geometry::Rigid3d truth_frame =
        ConventionalTruthFrame(simulator.world_from_mirror0(), true_scan);
    {
      const Eigen::Matrix<double, 6, 1> sd = out.mirror0_cov.diagonal().cwiseSqrt();
      const Eigen::Vector3d er = geometry::So3Log(out.world_from_mirror0.RotationMatrix() *
                                                  truth_frame.RotationMatrix().transpose());
      const Eigen::Vector3d et3 = out.world_from_mirror0.translation - truth_frame.translation;
      {
        const Eigen::Matrix3d r0 = truth_frame.RotationMatrix();
        const Eigen::Vector3d el = r0.transpose() * er;
        const Eigen::Matrix3d cl = r0.transpose() * out.mirror0_cov.topLeftCorner<3, 3>() * r0;
        std::printf("  frame rot err in {0} (%.4f %.4f %.4f) deg sigma (%.4f %.4f %.4f)\n",
                    el.x() * common::kDegPerRad, el.y() * common::kDegPerRad,
                    el.z() * common::kDegPerRad, std::sqrt(cl(0, 0)) * common::kDegPerRad,
                    std::sqrt(cl(1, 1)) * common::kDegPerRad,
                    std::sqrt(cl(2, 2)) * common::kDegPerRad);
      }
      std::printf(
          "  frame err rot (%.4f %.4f %.4f) deg sigma (%.4f %.4f %.4f); origin (%.3f %.3f "
          "%.3f) sigma (%.3f %.3f %.3f)\n",
          er.x() * common::kDegPerRad, er.y() * common::kDegPerRad, er.z() * common::kDegPerRad,
          sd(0) * common::kDegPerRad, sd(1) * common::kDegPerRad, sd(2) * common::kDegPerRad,
          et3.x(), et3.y(), et3.z(), sd(3), sd(4), sd(5));
    }
    {
      // Mahalanobis errors of the shared parameters (c1/c2 from world, beams) against truth.
      const MleResult& m = out.mle;
      auto transform_err = [](const geometry::Rigid3d& est, const geometry::Rigid3d& truth) {
        Eigen::Matrix<double, 6, 1> e;
        e.head<3>() = geometry::So3Log(truth.RotationMatrix() * est.RotationMatrix().transpose());
        e.tail<3>() = truth.translation - est.translation;
        return e;
      };
      auto maha = [&](const Eigen::VectorXd& e, int off) {
        const Eigen::MatrixXd c = m.other_cov.block(off, off, e.size(), e.size());
        return e.dot(c.ldlt().solve(e));
      };
      const auto e1 = transform_err(m.estimate.c1_from_world, simulator.c1_from_world());
      const auto e2 = transform_err(m.estimate.c2_from_world, simulator.c2_from_world());
      std::printf("  chi2/6: c1_from_world %.2f  c2_from_world %.2f\n", maha(e1, 0) / 6,
                  maha(e2, m.OffsetC2()) / 6);
      for (size_t b = 0; b < m.estimate.beams.size(); ++b) {
        const geometry::Line& l = m.estimate.beams[b];
        geometry::Line t = simulator.beams_in_world()[out.beams[b].beam - 1];
        if (t.v.dot(l.v) < 0) t = geometry::Line{-t.v, -t.m};
        const Eigen::Matrix<double, 3, 2> u = TangentBasis(l.v);
        const Eigen::Vector3d p0 = l.ClosestPointToOrigin();
        // Truth line meets the plane through p0 normal to v0.
        const Eigen::Vector3d pt = t.PointAt(t.Parameter(p0) + 0.0);
        const double s = (p0 - t.ClosestPointToOrigin()).dot(l.v) / t.v.dot(l.v);
        const Eigen::Vector3d q = t.ClosestPointToOrigin() + s * t.v;
        (void)pt;
        Eigen::Vector4d e;
        e.head<2>() = u.transpose() * (t.v / t.v.dot(l.v));
        e.tail<2>() = u.transpose() * (q - p0);
        std::printf("  beam %d: angle err %.4f deg, chi2/4 %.2f\n", out.beams[b].beam,
                    geometry::AngleBetween(l.v, t.v) * common::kDegPerRad,
                    maha(e, m.OffsetBeam(b)) / 4);
        // The direction sigma summary.json reports (SummariseSolve: the RMS angle).
        zbeam.Add(geometry::AngleBetween(l.v, t.v) / m.BeamDirectionSigmaRad(static_cast<int>(b)));
      }
    }
    for (const auto& sp : out.support_planes) {
      double t = 0;
      for (const auto& tr : simulator.triggers())
        if (tr.j == sp.j) t = tr.t_s;
      const auto mode = sp.kind == dataset::Step2Kind::kNeutral ? sim::DriveMode::kOff
                                                                : sim::DriveMode::kFastOnly;
      geometry::Plane tp = simulator.MirrorPlaneInWorld(t, mode);
      if (tp.n.dot(sp.plane_in_world.n) < 0) tp = geometry::Plane{-tp.n, -tp.d};
      const Eigen::Vector3d e = PlaneToChart(sp.plane_in_world, tp);
      // The normal in {W} against summary.json's rms_sigma_normal_world_deg's per-plane term.
      znormal.Add(e.head<2>().norm() / DirectionSigmaRad(sp.cov.topLeftCorner<2, 2>()));
      const auto pose = geometry::PoseFromWorldPlane(truth_frame, tp);
      std::printf(
          "  %s j=%d alpha %.2f: err (%.4f %.4f deg, %.4f mm) sd (%.4f %.4f, %.4f) chi2/3 %.2f\n",
          dataset::ToString(sp.kind), sp.j, pose.alpha_rad * common::kDegPerRad,
          e(0) * common::kDegPerRad, e(1) * common::kDegPerRad, e(2),
          std::sqrt(sp.cov(0, 0)) * common::kDegPerRad,
          std::sqrt(sp.cov(1, 1)) * common::kDegPerRad, std::sqrt(sp.cov(2, 2)),
          e.dot(sp.cov.ldlt().solve(e)) / 3);
    }
    Acc sa, sb, st, et;
    for (size_t k = 0; k < out.planes.size(); ++k) {
      const auto& row = out.planes[k];
      const auto tp = geometry::PoseFromWorldPlane(truth_frame, true_scan[k]);
      const Eigen::Vector3d e(row.alpha_deg - tp.alpha_rad * common::kDegPerRad,
                              row.beta_deg - tp.beta_rad * common::kDegPerRad,
                              row.trans_mm - tp.trans_mm);
      const Eigen::Vector3d s(row.sigma_alpha_deg, row.sigma_beta_deg, row.sigma_trans_mm);
      sa.Add(e(0) / s(0)), sb.Add(e(1) / s(1)), st.Add(e(2) / s(2));
      za.Add(e(0) / s(0)), zb.Add(e(1) / s(1)), zt.Add(e(2) / s(2));
      et.Add(e(2)), trans_err.Add(e(2));
    }
    std::printf("seed %d: trans error vs truth RMS %.4f mm\n", seed + 10, et.Rms());
    Acc sv;
    for (const auto& v : out.validation) sv.Add(v.normalised_error), zv.Add(v.normalised_error);
    std::printf(
        "seed %d: %zu planes, normalised RMS alpha %.2f beta %.2f trans %.2f, "
        "validation %.2f (%d dots), dot factor %.3f corner factor %.3f, dropped %zu\n",
        seed + 10, out.planes.size(), sa.Rms(), sb.Rms(), st.Rms(), sv.Rms(), sv.n,
        out.mle.dot_variance_factor, out.mle.corner_variance_factor, out.dropped.size());
    for (int f = 0; f < kNumFamilies; ++f)
      std::printf("  %s: factor %.4f redundancy %.1f\n", MleFamilyName(f),
                  out.mle.variance_factor[f], out.mle.redundancy[f]);
    std::fflush(stdout);
  }
  std::printf("all seeds: normalised RMS alpha %.2f beta %.2f trans %.2f validation %.2f\n",
              za.Rms(), zb.Rms(), zt.Rms(), zv.Rms());
  std::printf("trans error vs truth RMS %.4f mm\n", trans_err.Rms());
  // In {W}: the beams' directions and the neutral / fast-only normals against their RMS-angle
  // sigmas (summary.json beam_direction_sigma_deg, rms_sigma_normal_world_deg). Per scene these
  // are one draw of step 1's common beam tilt, so the bounds are wider than the poses'.
  std::printf("in {W}: beam direction error / sigma RMS %.2f (%d), normals %.2f (%d)\n",
              zbeam.Rms(), zbeam.n, znormal.Rms(), znormal.n);
  // Measured: beams 0.79 (24), normals 0.55 (104: conservative on these scenes); over 29 random
  // scenes through the command line (README, session 24) 1.18 and 1.13.
  EXPECT_GE(zbeam.Rms(), 0.5);
  EXPECT_LE(zbeam.Rms(), 1.6);
  EXPECT_GE(znormal.Rms(), 0.35);
  EXPECT_LE(znormal.Rms(), 1.6);
  EXPECT_EQ(skipped, 0);
  EXPECT_LT(trans_err.Rms(), 0.02);  // measured 0.0085 mm
  for (double z : {za.Rms(), zb.Rms(), zt.Rms(), zv.Rms()}) {
    EXPECT_GE(z, 0.75);
    EXPECT_LE(z, 1.25);
  }
}

}  // namespace
}  // namespace msmcal::solver
