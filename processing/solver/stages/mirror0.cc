#include "processing/solver/stages/mirror0.h"

#include <algorithm>

#include "processing/geometry/mirror_frame.h"
#include "processing/solver/home_frame.h"

namespace msmcal::solver {

using dataset::Step2Kind;
using geometry::Plane;

PlaneRoles RolesOf(const std::vector<std::pair<Step2Kind, int>>& plane_keys) {
  PlaneRoles r;
  int& neutral_index = r.neutral;
  std::vector<int>& fast_index = r.fast_only;
  std::vector<int>& scan_index = r.scan;
  for (int p = 0; p < static_cast<int>(plane_keys.size()); ++p) {
    if (plane_keys[p].first == Step2Kind::kNeutral) neutral_index = p;
    if (plane_keys[p].first == Step2Kind::kFastOnly) fast_index.push_back(p);
    if (plane_keys[p].first == Step2Kind::kScan) scan_index.push_back(p);
  }
  return r;
}

std::vector<int> ScanPlanesByJ(const std::vector<std::pair<Step2Kind, int>>& plane_keys,
                               const PlaneRoles& roles) {
  std::vector<int> scan_planes = roles.scan;
  std::sort(scan_planes.begin(), scan_planes.end(),
            [&](int a, int b) { return plane_keys[a].second < plane_keys[b].second; });
  return scan_planes;
}

geometry::Rigid3d Mirror0FromPlanes(const std::vector<Plane>& planes, const PlaneRoles& roles) {
  std::vector<Plane> fast, scan;
  for (int p : roles.fast_only) fast.push_back(planes[p]);
  for (int p : roles.scan) scan.push_back(planes[p]);
  return HomeFrame(planes[roles.neutral],
                   geometry::FastAxisWithNeutral(planes[roles.neutral], fast), scan);
}

Mirror0 EstimateMirror0(const std::vector<std::pair<Step2Kind, int>>& plane_keys,
                        const MleResult& mle) {
  Mirror0 out;
  out.roles = RolesOf(plane_keys);
  const Estimate& est = mle.estimate;
  const int neutral_index = out.roles.neutral;
  const std::vector<int>& fast_index = out.roles.fast_only;
  out.world_from_mirror0 = Mirror0FromPlanes(est.planes, out.roles);
  {
    std::vector<int> support{neutral_index};
    std::vector<int> fast_sorted = fast_index;
    std::sort(fast_sorted.begin(), fast_sorted.end(),
              [&](int a, int b) { return plane_keys[a].second < plane_keys[b].second; });
    support.insert(support.end(), fast_sorted.begin(), fast_sorted.end());
    for (int p : support)
      out.support_planes.push_back(
          {plane_keys[p].first, plane_keys[p].second, est.planes[p], mle.plane_cov[p]});
  }
  return out;
}

}  // namespace msmcal::solver
