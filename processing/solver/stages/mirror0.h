#pragma once
// Stage: the mirror home frame {0} (MSM paper Sec. V-A3, eq. 11; home_frame.h): Z the neutral
// plane's normal, X the fast axis from the fast-only planes, the origin on the neutral plane
// closest in least squares to the scan planes.

#include <utility>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/geometry/plane_line.h"
#include "processing/geometry/rigid3.h"
#include "processing/solver/mle.h"
#include "processing/solver/solve_types.h"

namespace msmcal::solver {

// Which mirror planes (by index) play which part in {0}.
struct PlaneRoles {
  int neutral = -1;
  std::vector<int> fast_only;  // ascending plane index
  std::vector<int> scan;       // ascending plane index
};
PlaneRoles RolesOf(const std::vector<std::pair<dataset::Step2Kind, int>>& plane_keys);

// The scan planes by ascending trigger index j (the order of mirror_planes.csv).
std::vector<int> ScanPlanesByJ(const std::vector<std::pair<dataset::Step2Kind, int>>& plane_keys,
                               const PlaneRoles& roles);

// {0} from the planes (all planes by index; `roles` picks the ones that define it).
geometry::Rigid3d Mirror0FromPlanes(const std::vector<geometry::Plane>& planes,
                                    const PlaneRoles& roles);

struct Mirror0 {
  PlaneRoles roles;
  geometry::Rigid3d world_from_mirror0;
  std::vector<SupportPlane> support_planes;  // neutral, then fast-only by ascending j
};
// {0} from the MLE's planes, with the support planes and their covariances.
Mirror0 EstimateMirror0(const std::vector<std::pair<dataset::Step2Kind, int>>& plane_keys,
                        const MleResult& mle);

}  // namespace msmcal::solver
