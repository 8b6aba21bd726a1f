#include "processing/solver/stages/estimate.h"

#include "processing/solver/initialise.h"

namespace msmcal::solver {

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
    int dropped = 0;
    obs.corners = MergeRepeatedViews(obs.corners, corners_clear, &dropped);
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
