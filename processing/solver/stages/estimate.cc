#include "processing/solver/stages/estimate.h"

#include <algorithm>
#include <cstdio>

#include "processing/solver/initialise.h"

namespace msmcal::solver {

namespace {

double Median(std::vector<double> v) {
  const size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h), v.end());
  if (v.size() % 2 == 1) return v[h];
  const double hi = v[h];
  return 0.5 * (hi + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h)));
}

// The sets of each repeated view (same board view, pose and corner count), in order.
std::vector<std::vector<size_t>> RepeatedViews(const std::vector<CornerSet>& sets) {
  std::vector<std::vector<size_t>> views;
  for (size_t k = 0; k < sets.size(); ++k) {
    size_t v = 0;
    while (v < views.size()) {
      const CornerSet& first = sets[views[v][0]];
      if (first.view == sets[k].view && first.pose == sets[k].pose &&
          first.px.size() == sets[k].px.size())
        break;
      ++v;
    }
    if (v == views.size()) views.emplace_back();
    views[v].push_back(k);
  }
  return views;
}

}  // namespace

CornerConsistency MarkInconsistentCorners(const std::vector<CornerSet>& sets,
                                          std::vector<std::vector<char>>* clear,
                                          const CornerConsistencyOptions& o) {
  CornerConsistency out;
  std::vector<char> affected(sets.size(), 0);
  const size_t min_frames = static_cast<size_t>(std::max(o.min_frames, 3));
  for (const std::vector<size_t>& view : RepeatedViews(sets)) {
    if (view.size() < min_frames) continue;
    const size_t n = sets[view[0]].px.size();
    auto is_clear = [&](size_t k, size_t i) { return (*clear)[k][i] != 0; };
    // Each corner's median over its clear frames, then each frame's median shift from those,
    // then the medians again with the shifts taken off.
    std::vector<Eigen::Vector2d> shift(view.size(), Eigen::Vector2d::Zero());
    std::vector<Eigen::Vector2d> centre(n, Eigen::Vector2d::Zero());
    std::vector<char> tested(n, 0);
    for (int pass = 0; pass < 2; ++pass) {
      for (size_t i = 0; i < n; ++i) {
        std::vector<double> x, y;
        for (size_t f = 0; f < view.size(); ++f) {
          if (!is_clear(view[f], i)) continue;
          x.push_back(sets[view[f]].px[i].x() - shift[f].x());
          y.push_back(sets[view[f]].px[i].y() - shift[f].y());
        }
        tested[i] = x.size() >= min_frames;
        if (tested[i]) centre[i] = {Median(x), Median(y)};
      }
      if (pass == 1) break;
      for (size_t f = 0; f < view.size(); ++f) {
        std::vector<double> dx, dy;
        for (size_t i = 0; i < n; ++i) {
          if (!tested[i] || !is_clear(view[f], i)) continue;
          dx.push_back(sets[view[f]].px[i].x() - centre[i].x());
          dy.push_back(sets[view[f]].px[i].y() - centre[i].y());
        }
        if (!dx.empty()) shift[f] = {Median(dx), Median(dy)};
      }
    }
    std::vector<double> dist;
    for (size_t f = 0; f < view.size(); ++f)
      for (size_t i = 0; i < n; ++i)
        if (tested[i] && is_clear(view[f], i))
          dist.push_back((sets[view[f]].px[i] - shift[f] - centre[i]).norm());
    if (dist.empty()) continue;
    const double sigma = Median(dist) / 1.1774;  // Rayleigh: median = sigma sqrt(2 ln 2)
    const double threshold = std::max(o.k_sigma * sigma, o.min_threshold_px);
    out.max_threshold_px = std::max(out.max_threshold_px, threshold);
    for (size_t f = 0; f < view.size(); ++f)
      for (size_t i = 0; i < n; ++i) {
        if (!tested[i] || !is_clear(view[f], i)) continue;
        if ((sets[view[f]].px[i] - shift[f] - centre[i]).norm() <= threshold) continue;
        (*clear)[view[f]][i] = 0;
        ++out.marked;
        affected[view[f]] = 1;
      }
  }
  out.frames_affected = static_cast<int>(std::count(affected.begin(), affected.end(), 1));
  return out;
}

std::vector<CornerSet> MergeRepeatedViews(const std::vector<CornerSet>& sets,
                                          const std::vector<std::vector<char>>& clear,
                                          int* dropped) {
  std::vector<CornerSet> sum;
  std::vector<std::vector<int>> count;
  for (size_t k = 0; k < sets.size(); ++k) {
    const CornerSet& cs = sets[k];
    size_t v = 0;
    while (v < sum.size() &&
           !(sum[v].view == cs.view && sum[v].pose == cs.pose && sum[v].px.size() == cs.px.size()))
      ++v;
    if (v == sum.size()) {
      sum.push_back(cs);
      for (auto& p : sum.back().px) p.setZero();
      count.emplace_back(cs.px.size(), 0);
    }
    for (size_t i = 0; i < cs.px.size(); ++i) {
      if (!clear[k][i]) continue;
      sum[v].px[i] += cs.px[i];
      ++count[v][i];
    }
  }
  std::vector<CornerSet> out;
  *dropped = 0;
  for (size_t v = 0; v < sum.size(); ++v) {
    CornerSet m{sum[v].view, sum[v].pose, {}, {}};
    for (size_t i = 0; i < sum[v].px.size(); ++i) {
      if (count[v][i] == 0) {
        ++*dropped;
        continue;
      }
      m.points_in_board.push_back(sum[v].points_in_board[i]);
      m.px.push_back(sum[v].px[i] / count[v][i]);
    }
    if (m.px.size() >= 4)
      out.push_back(std::move(m));
    else
      *dropped += static_cast<int>(m.px.size());
  }
  return out;
}

MleEstimate EstimateMle(Observations obs_in, const std::vector<std::vector<char>>& corners_clear,
                        const MleOptions& o) {
  MleEstimate out;
  out.obs = std::move(obs_in);
  Observations& obs = out.obs;
  {
    std::vector<std::vector<char>> clear = corners_clear;
    const CornerConsistency consistency = MarkInconsistentCorners(obs.corners, &clear);
    if (consistency.marked > 0) {
      char threshold[32];
      std::snprintf(threshold, sizeof threshold, "%.3f", consistency.max_threshold_px);
      out.log.notes.push_back(
          "corners: " + std::to_string(consistency.marked) + " corner observation(s) in " +
          std::to_string(consistency.frames_affected) + " frame(s) left out: more than " +
          threshold +
          " px from where the other frames of their view put them (a plate or a glint over "
          "the squares around them)");
    }
    int dropped = 0;
    obs.corners = MergeRepeatedViews(obs.corners, clear, &dropped);
    if (dropped > 0)
      out.log.notes.push_back("corners: " + std::to_string(dropped) +
                              " board corner(s) left out: a laser dot reached their refinement "
                              "window in every frame of their view (or too few corners of the view "
                              "were left)");
  }
  std::string err;
  const auto init = InitialEstimate(obs, &err);
  if (!init) {
    out.log.error = "initial values: " + err;
    return out;
  }
  out.mle = SolveMle(obs, *init, o);
  if (!out.mle.usable) out.log.error = "maximum-likelihood solve failed: " + out.mle.message;
  return out;
}

}  // namespace msmcal::solver
