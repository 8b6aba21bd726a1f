#include "processing/solver/stages/common.h"

#include <algorithm>
#include <limits>
#include <numeric>

namespace msmcal::solver {

using geometry::Rigid3d;

std::string SizeText(const dataset::BoardSpec& b) {
  return std::to_string(b.cols) + "x" + std::to_string(b.rows);
}

std::vector<Eigen::Vector3d> BoardPoints(const dataset::BoardSpec& b) {
  std::vector<Eigen::Vector3d> p;
  for (int r = 0; r < b.rows; ++r)
    for (int c = 0; c < b.cols; ++c) p.emplace_back(c * b.square_mm, r * b.square_mm, 0.0);
  return p;
}

// Best assignment of `n` items to `n` slots minimising sum cost(i, slot): brute force up to 7,
// greedy above.
std::vector<int> BestPermutation(int n, const std::function<double(int, int)>& cost) {
  std::vector<int> perm(n);
  std::iota(perm.begin(), perm.end(), 0);
  if (n > 7) {
    std::vector<int> out(n, -1);
    std::vector<bool> used(n, false);
    for (int i = 0; i < n; ++i) {
      int best = -1;
      for (int s = 0; s < n; ++s)
        if (!used[s] && (best < 0 || cost(i, s) < cost(i, best))) best = s;
      out[i] = best;
      used[best] = true;
    }
    return out;
  }
  std::vector<int> best = perm;
  double best_cost = 1e300;
  do {
    double c = 0;
    for (int i = 0; i < n && c < best_cost; ++i) c += cost(i, perm[i]);
    if (c < best_cost) {
      best_cost = c;
      best = perm;
    }
  } while (std::next_permutation(perm.begin(), perm.end()));
  return best;
}

std::vector<int> BestInjection(int items, int slots, const std::function<double(int, int)>& cost,
                               double unassigned) {
  std::vector<std::vector<double>> c(items, std::vector<double>(slots));
  for (int i = 0; i < items; ++i)
    for (int s = 0; s < slots; ++s) c[i][s] = cost(i, s);
  std::vector<int> cur(items, -1), best(items, -1);
  std::vector<bool> used(slots, false);
  double best_cost = std::numeric_limits<double>::infinity();
  std::function<void(int, double)> visit = [&](int i, double sum) {
    if (sum >= best_cost) return;
    if (i == items) {
      best_cost = sum;
      best = cur;
      return;
    }
    for (int s = 0; s < slots; ++s) {
      if (used[s] || !(c[i][s] < unassigned)) continue;
      used[s] = true;
      cur[i] = s;
      visit(i + 1, sum + c[i][s]);
      used[s] = false;
    }
    cur[i] = -1;
    visit(i + 1, sum + unassigned);
  };
  visit(0, 0.0);
  return best;
}

// RMS distance between a board's detected corners and their projection through the PnP pose;
// -1 if none projects.
double ReprojectionRms(const geometry::CameraModel& camera, const Rigid3d& cam_from_board,
                       const std::vector<Eigen::Vector3d>& pts,
                       const std::vector<Eigen::Vector2d>& px) {
  double s2 = 0;
  int n = 0;
  for (size_t i = 0; i < pts.size() && i < px.size(); ++i)
    if (const auto p = camera.Project(cam_from_board * pts[i])) {
      s2 += (*p - px[i]).squaredNorm();
      ++n;
    }
  return n ? std::sqrt(s2 / n) : -1.0;
}

std::optional<int> BeamTable::IndexOf(int id) const {
  const auto it = index_of_id.find(id);
  if (it == index_of_id.end()) return std::nullopt;
  return it->second;
}

BeamTable MakeBeamTable(const std::vector<dataset::BeamSpec>& beams) {
  BeamTable t;
  for (const auto& b : beams) {
    t.index_of_id[b.id] = static_cast<int>(t.ids.size());
    t.ids.push_back(b.id);
    t.is_estimate.push_back(b.role == dataset::BeamRole::kEstimate);
  }
  return t;
}

std::string UnknownBeamError(const std::string& file, int id) {
  return "session.yaml: frame " + file + " lists beam " + std::to_string(id) +
         " which is not in beams";
}

}  // namespace msmcal::solver
