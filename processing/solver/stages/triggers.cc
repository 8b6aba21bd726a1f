#include "processing/solver/stages/triggers.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <sstream>

#include "common/units.h"
#include "processing/geometry/mirror_frame.h"

namespace msmcal::solver {
namespace {

using dataset::Step2Kind;
using geometry::Plane;
using geometry::Rigid3d;

Eigen::VectorXd Features(double t, bool slow_on, double wf, double ws, bool harmonics) {
  Eigen::VectorXd f(harmonics ? 9 : 5);
  const double m = slow_on ? 1.0 : 0.0;
  f(0) = 1;
  f(1) = std::sin(wf * t);
  f(2) = std::cos(wf * t);
  f(3) = m * std::sin(ws * t);
  f(4) = m * std::cos(ws * t);
  if (harmonics) {
    f(5) = std::sin(2 * wf * t);
    f(6) = std::cos(2 * wf * t);
    f(7) = m * std::sin(2 * ws * t);
    f(8) = m * std::cos(2 * ws * t);
  }
  return f;
}

}  // namespace

Eigen::Vector2d TriggerModel::Predict(double t_s, bool slow_on) const {
  return coef.transpose() *
         Features(t_s, slow_on, 2 * M_PI * fast_hz, 2 * M_PI * slow_hz, harmonics);
}

std::vector<int> AssignTriggers(const std::vector<TriggerFrame>& frames,
                                const std::vector<TriggerGroup>& groups,
                                const std::vector<Eigen::Vector2d>& neutral_angles_deg,
                                double fast_hz, double slow_hz, const PipelineOptions& o,
                                std::string* note, TriggerModel* model) {
  const double wf = 2 * M_PI * fast_hz, ws = 2 * M_PI * slow_hz;
  std::vector<std::vector<int>> of_frame(frames.size());
  for (size_t g = 0; g < groups.size(); ++g)
    of_frame[groups[g].frame].push_back(static_cast<int>(g));
  std::vector<int> slot(groups.size(), 0);
  auto fit = [&](const std::vector<std::pair<int, int>>& labelled, bool harmonics,
                 Eigen::MatrixXd* coef) {
    const int p = harmonics ? 9 : 5;
    const int n = static_cast<int>(labelled.size() + neutral_angles_deg.size());
    Eigen::MatrixXd a(n, p);
    Eigen::MatrixXd y(n, 2);
    int r = 0;
    for (const auto& [g, s] : labelled) {
      const auto& fr = frames[groups[g].frame];
      a.row(r) = Features(fr.t_s[s], fr.slow_on, wf, ws, harmonics).transpose();
      y.row(r++) = groups[g].angles_deg.transpose();
    }
    for (const auto& na : neutral_angles_deg) {
      a.row(r).setZero();
      a(r, 0) = 1;
      y.row(r++) = na.transpose();
    }
    // Small ridge keeps under-determined samples solvable.
    const Eigen::MatrixXd ata = a.transpose() * a + 1e-9 * Eigen::MatrixXd::Identity(p, p);
    *coef = ata.ldlt().solve(a.transpose() * y);
  };
  auto assign = [&](const Eigen::MatrixXd& coef, bool harmonics, std::vector<int>* out) {
    const double thr2 = o.ransac_inlier_deg * o.ransac_inlier_deg;
    double score = 0;
    for (size_t f = 0; f < frames.size(); ++f) {
      const auto& gs = of_frame[f];
      if (gs.empty()) continue;
      const int n = static_cast<int>(frames[f].t_s.size());
      std::vector<Eigen::Vector2d> pred(n);
      for (int s = 0; s < n; ++s)
        pred[s] =
            coef.transpose() * Features(frames[f].t_s[s], frames[f].slow_on, wf, ws, harmonics);
      auto cost = [&](int i, int s) {
        if (i >= static_cast<int>(gs.size())) return 0.0;
        return std::min((groups[gs[i]].angles_deg - pred[s]).squaredNorm(), thr2);
      };
      const std::vector<int> perm = BestPermutation(n, cost);
      for (size_t i = 0; i < gs.size(); ++i) {
        const double c = cost(static_cast<int>(i), perm[i]);
        score += c;
        if (out) (*out)[gs[i]] = c < thr2 ? perm[i] : -1;
      }
    }
    return score;
  };
  std::vector<int> multi;
  for (size_t f = 0; f < frames.size(); ++f)
    if (!of_frame[f].empty()) multi.push_back(static_cast<int>(f));
  std::mt19937_64 rng(o.seed);
  Eigen::MatrixXd best_coef;
  double best_score = 1e300;
  const int sample = neutral_angles_deg.empty() ? 5 : 4;
  for (int it = 0; it < o.ransac_iterations && !multi.empty(); ++it) {
    std::vector<std::pair<int, int>> labelled;
    for (int k = 0; k < sample; ++k) {
      const int f = multi[std::uniform_int_distribution<int>(0, multi.size() - 1)(rng)];
      const auto& gs = of_frame[f];
      const int g = gs[std::uniform_int_distribution<int>(0, gs.size() - 1)(rng)];
      const int s = std::uniform_int_distribution<int>(0, frames[f].t_s.size() - 1)(rng);
      labelled.emplace_back(g, s);
    }
    Eigen::MatrixXd coef;
    fit(labelled, false, &coef);
    const double score = assign(coef, false, nullptr);
    if (score < best_score) {
      best_score = score;
      best_coef = coef;
    }
  }
  if (multi.empty()) return slot;
  assign(best_coef, false, &slot);
  Eigen::MatrixXd coef = best_coef;
  bool harmonics = false;
  // Refined on the inliers only: a plane from a wrong pairing of dots (tens of degrees off) would
  // otherwise pull the least-squares model, and with it every assignment, off.
  for (int round = 0; round < 4; ++round) {
    std::vector<std::pair<int, int>> labelled;
    for (size_t g = 0; g < groups.size(); ++g)
      if (slot[g] >= 0) labelled.emplace_back(static_cast<int>(g), slot[g]);
    if (labelled.size() + neutral_angles_deg.size() < 5) break;
    harmonics = labelled.size() + neutral_angles_deg.size() >= 18;
    fit(labelled, harmonics, &coef);
    assign(coef, harmonics, &slot);
  }
  if (model) *model = TriggerModel{coef, harmonics, fast_hz, slow_hz};
  if (note) {
    double sum2 = 0;
    size_t inliers = 0;
    for (size_t g = 0; g < groups.size(); ++g) {
      if (slot[g] < 0) continue;
      const auto& fr = frames[groups[g].frame];
      const Eigen::Vector2d pred =
          coef.transpose() * Features(fr.t_s[slot[g]], fr.slow_on, wf, ws, harmonics);
      sum2 += (groups[g].angles_deg - pred).squaredNorm();
      ++inliers;
    }
    std::ostringstream s;
    s << "trigger assignment: " << groups.size() << " groups in " << multi.size()
      << " multi-trigger frames, drive-phase model RMS "
      << std::sqrt(sum2 / std::max<size_t>(1, inliers)) << " deg";
    if (inliers < groups.size())
      s << " over " << inliers << " groups (" << groups.size() - inliers << " more than "
        << o.ransac_inlier_deg << " deg off the model left out)";
    *note = s.str();
  }
  return slot;
}

TriggerAssignment AssignTriggerSlots(const std::vector<Step2View>& s2, std::vector<Group> groups,
                                     std::vector<Group> recovered,
                                     const std::vector<dataset::Trigger>& triggers,
                                     const dataset::Drive& drive, const PipelineOptions& o) {
  TriggerAssignment out;
  // Provisional home frame for the trigger assignment.
  std::vector<Plane> neutral_planes, fast_planes;
  for (const auto& g : groups) {
    if (s2[g.frame].frame.kind == Step2Kind::kNeutral) neutral_planes.push_back(g.plane);
    if (s2[g.frame].frame.kind == Step2Kind::kFastOnly) fast_planes.push_back(g.plane);
  }
  Eigen::Vector3d n0 = Eigen::Vector3d::Zero();
  for (const auto& p : neutral_planes.empty() ? std::vector<Plane>{} : neutral_planes) n0 += p.n;
  if (neutral_planes.empty())
    for (const auto& g : groups) n0 += g.plane.n;
  if (groups.empty()) {
    out.log.error = "step2: no usable frame with reflected dots";
    return out;
  }
  n0.normalize();
  const Eigen::Vector3d fast0 = !fast_planes.empty()
                                    ? geometry::FastAxisWithNeutral(Plane{n0, 0.0}, fast_planes)
                                    : TangentBasis(n0).col(0);
  const Rigid3d provisional = geometry::MirrorHomeFrame(n0, fast0, Eigen::Vector3d::Zero());
  auto angles_of = [&](const Plane& p) {
    const auto pose = geometry::PoseFromWorldPlane(provisional, p);
    return Eigen::Vector2d(pose.alpha_rad * common::kDegPerRad, pose.beta_rad * common::kDegPerRad);
  };
  {
    std::vector<TriggerFrame> tframes(s2.size());
    std::vector<TriggerGroup> tgroups;
    std::vector<int> multi_index;
    std::map<int, double> t_of_j;
    for (const auto& t : triggers) t_of_j[t.j] = t.t_s;
    for (size_t f = 0; f < s2.size(); ++f) {
      tframes[f].slow_on = s2[f].frame.kind == Step2Kind::kScan;
      for (int j : s2[f].frame.triggers) {
        if (!t_of_j.count(j)) {
          out.log.error = "session.yaml: frame " + s2[f].frame.file + " lists trigger " +
                          std::to_string(j) + " which is not in triggers";
          return out;
        }
        tframes[f].t_s.push_back(t_of_j[j]);
      }
    }
    for (size_t g = 0; g < groups.size(); ++g) {
      const auto* fr = &s2[groups[g].frame].frame;
      if (fr->kind == Step2Kind::kNeutral || fr->triggers.size() <= 1) continue;
      tgroups.push_back({groups[g].frame, angles_of(groups[g].plane)});
      multi_index.push_back(static_cast<int>(g));
    }
    std::vector<Eigen::Vector2d> neutral_angles;
    for (const auto& p : neutral_planes) neutral_angles.push_back(angles_of(p));
    if (!tgroups.empty()) {
      std::string note;
      TriggerModel model;
      const auto slots = AssignTriggers(tframes, tgroups, neutral_angles, drive.fast.frequency_hz,
                                        drive.slow.frequency_hz, o, &note, &model);
      for (size_t k = 0; k < multi_index.size(); ++k) groups[multi_index[k]].slot = slots[k];
      out.log.notes.push_back(note);
      // More than half off the model: the trigger times or the drive do not describe these
      // frames (or the grouping failed); no assignment to trust.
      const size_t off = static_cast<size_t>(std::count(slots.begin(), slots.end(), -1));
      if (2 * off > slots.size()) {
        std::ostringstream msg;
        msg << "step2: trigger assignment failed: " << off << " of " << slots.size()
            << " mirror planes of multi-trigger frames fit no drive-phase model within "
            << o.ransac_inlier_deg
            << " deg (check the trigger times and drive frequencies in session.yaml)";
        out.log.error = msg.str();
        return out;
      }
      for (size_t g = 0; g < groups.size();) {
        if (groups[g].slot >= 0) {
          ++g;
          continue;
        }
        out.off_model.push_back(groups[g].frame);
        out.log.notes.push_back(s2[groups[g].frame].frame.file +
                                ": a mirror plane off the drive-phase model (a wrong pairing of "
                                "dots) left out");
        groups.erase(groups.begin() + static_cast<std::ptrdiff_t>(g));
      }
      // Tentative groups: the one slot their frame's complete groups left free, if the model
      // predicts their angles there within a quarter of the RANSAC inlier threshold (wrong beam
      // pairings are degrees off; the model's RMS is ~0.001 deg on the simulator).
      for (auto& g : recovered) {
        const auto* fr = &s2[g.frame].frame;
        std::vector<bool> taken(fr->triggers.size(), false);
        for (const auto& other : groups)
          if (other.frame == g.frame) taken[other.slot] = true;
        const int free_slot =
            static_cast<int>(std::find(taken.begin(), taken.end(), false) - taken.begin());
        if (free_slot >= static_cast<int>(taken.size())) continue;
        const double off_deg = (angles_of(g.plane) - model.Predict(tframes[g.frame].t_s[free_slot],
                                                                   tframes[g.frame].slow_on))
                                   .norm();
        std::ostringstream msg;
        msg << fr->file << ": trigger " << fr->triggers[free_slot] << " (its held-out dot "
            << "missing) from the estimate beams' dots alone, " << off_deg
            << " deg from the drive-phase model: ";
        if (off_deg <= 0.25 * o.ransac_inlier_deg) {
          g.slot = free_slot;
          groups.push_back(g);
          msg << "kept";
        } else {
          msg << "not kept (> " << 0.25 * o.ransac_inlier_deg << " deg)";
        }
        out.log.notes.push_back(msg.str());
      }
    }
  }
  out.groups = std::move(groups);
  return out;
}

MirrorPlanes CollectMirrorPlanes(const std::vector<Step2View>& s2, const std::vector<Group>& groups,
                                 const BeamTable& beam_table) {
  MirrorPlanes out;
  const std::vector<bool>& is_estimate = beam_table.is_estimate;
  auto to_obs = [](const vision::Dot& d) { return PixelObs{d.px, d.cov_px2}; };
  std::map<std::pair<int, int>, int> plane_of_key;
  std::vector<std::pair<Step2Kind, int>>& plane_keys = out.keys;
  std::vector<ReflectedDot>& validation_dots = out.validation_dots;
  for (const auto& g : groups) {
    const auto* fr = &s2[g.frame].frame;
    const int j = fr->kind == Step2Kind::kNeutral ? -1 : fr->triggers[g.slot];
    const auto key = std::make_pair(static_cast<int>(fr->kind), j);
    auto it = plane_of_key.find(key);
    if (it == plane_of_key.end()) {
      it = plane_of_key.emplace(key, static_cast<int>(plane_keys.size())).first;
      plane_keys.emplace_back(fr->kind, j);
    }
    for (const auto& [b, d] : g.dot_of_beam) {
      const ReflectedDot rd{it->second, b, to_obs(s2[g.frame].dots[d]), s2[g.frame].near_edge[d]};
      (is_estimate[b] ? out.estimate_dots : validation_dots).push_back(rd);
    }
  }
  for (const auto& [kind, j] : plane_keys) {
    if (kind == Step2Kind::kNeutral) ++out.num_neutral;
    if (kind == Step2Kind::kFastOnly) ++out.num_fast_only;
    if (kind == Step2Kind::kScan) ++out.num_scan;
  }
  if (out.num_neutral == 0) {
    out.log.error = "step2: no usable neutral frame (needed for {0})";
  } else if (out.num_fast_only == 0) {
    out.log.error = "step2: no usable fast_only mirror plane; {0} needs >= 1 (>= 2 preferred)";
  } else if (out.num_fast_only == 1) {
    // {0}'s fast axis from that plane and the neutral one (geometry::FastAxisWithNeutral): they
    // must be tilted apart for the axis to be determined.
    double tilt_deg = 0;
    const Plane* neutral = nullptr;
    for (const auto& g : groups)
      if (s2[g.frame].frame.kind == Step2Kind::kNeutral) neutral = &g.plane;
    for (const auto& g : groups)
      if (neutral && s2[g.frame].frame.kind == Step2Kind::kFastOnly) {
        const double a = geometry::AngleBetween(neutral->n, g.plane.n) * common::kDegPerRad;
        tilt_deg = std::min(a, 180 - a);
      }
    std::ostringstream msg;
    msg << "step2: 1 usable fast_only mirror plane, " << tilt_deg << " deg from the neutral";
    if (tilt_deg < kMinSingleFastOnlyTiltDeg)
      out.log.error = msg.str() +
                      ": {0}'s fast axis needs a second fast_only plane or one tilted "
                      "at least " +
                      std::to_string(kMinSingleFastOnlyTiltDeg).substr(0, 3) +
                      " deg from the neutral";
    else
      out.log.notes.push_back(msg.str() +
                              ": {0}'s fast axis from it and the neutral plane (one fast_only "
                              "plane; two or more give it on their own)");
  }
  return out;
}

}  // namespace msmcal::solver
