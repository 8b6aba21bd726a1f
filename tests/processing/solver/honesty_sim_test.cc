// Honest sigmas on rendered images: over several simulated sessions (scene jittered per seed),
// the errors of the solved poses (alpha, beta, trans in {0}) against the simulator's truth in
// the same {0} convention, divided by their predicted sigmas, and the validation dots'
// normalised errors. Target (issue 6): unit RMS within +-25 %. NOT MET YET: over 8 seeds the
// RMS is alpha 1.60, beta 1.38, trans 1.38, validation 1.10 (docs/solver.md), with the default 4
// seeds 1.87 / 1.72 / 1.76 / 1.40; the bounds below are a regression guard on that state
// (neither the old 2-4x conservative nor grossly over-confident), NOT the acceptance check.
// MSMCAL_HONESTY_SEEDS=N runs N seeds (default 4).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>

#include "mocks/rig/rig_simulator.h"
#include "processing/geometry/mirror_frame.h"
#include "processing/solver/home_frame.h"
#include "processing/solver/pipeline.h"

namespace msmcal::solver {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

struct Acc {
  double z2 = 0;
  int n = 0;
  void Add(double z) { z2 += z * z, ++n; }
  double Rms() const { return n ? std::sqrt(z2 / n) : 0; }
};

TEST(HonestySimTest, NormalisedErrorsHaveUnitRms) {
  int num_seeds = 4;
  if (const char* e = std::getenv("MSMCAL_HONESTY_SEEDS")) num_seeds = std::atoi(e);
  Acc za, zb, zt, zv, trans_err;
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
    const ImageLoader load = [&](const std::string& file) -> cv::Mat {
      for (size_t i = 0; i < rec.step1.size(); ++i)
        if (rec.step1[i].file == file) return simulator.RenderStep1Frame(i);
      for (size_t i = 0; i < rec.step2.size(); ++i)
        if (rec.step2[i].file == file) return simulator.RenderStep2Frame(i);
      return cv::Mat();
    };
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
      std::printf(
          "  frame err rot (%.4f %.4f %.4f) deg sigma (%.4f %.4f %.4f); origin (%.3f %.3f "
          "%.3f) sigma (%.3f %.3f %.3f)\n",
          er.x() * kRadToDeg, er.y() * kRadToDeg, er.z() * kRadToDeg, sd(0) * kRadToDeg,
          sd(1) * kRadToDeg, sd(2) * kRadToDeg, et3.x(), et3.y(), et3.z(), sd(3), sd(4), sd(5));
    }
    Acc sa, sb, st, et;
    for (size_t k = 0; k < out.planes.size(); ++k) {
      const auto& row = out.planes[k];
      const auto tp = geometry::PoseFromWorldPlane(truth_frame, true_scan[k]);
      const Eigen::Vector3d e(row.alpha_deg - tp.alpha_rad * kRadToDeg,
                              row.beta_deg - tp.beta_rad * kRadToDeg, row.trans_mm - tp.trans_mm);
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
  EXPECT_LE(skipped, num_seeds / 4);
  EXPECT_LT(trans_err.Rms(), 0.08);
  for (double z : {za.Rms(), zb.Rms(), zt.Rms(), zv.Rms()}) {
    EXPECT_GT(z, 0.6);
    EXPECT_LT(z, 2.2);
  }
}

}  // namespace
}  // namespace msmcal::solver
