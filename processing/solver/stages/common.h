#pragma once
// Small helpers shared by the solver's stages (processing/solver/stages/*.h).

#include <Eigen/Core>
#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/units.h"
#include "processing/dataset/recording.h"
#include "processing/geometry/camera_model.h"
#include "processing/geometry/rigid3.h"
#include "processing/solver/solve_types.h"

namespace msmcal::solver {

// "13x8": a board's inner-corner grid, for messages.
std::string SizeText(const dataset::BoardSpec& b);

// A board's inner corners in its own frame (mm, z = 0), row by row.
std::vector<Eigen::Vector3d> BoardPoints(const dataset::BoardSpec& b);

// Best assignment of `n` items to `n` slots minimising sum cost(i, slot): brute force up to 7,
// greedy above. Returns slot per item.
std::vector<int> BestPermutation(int n, const std::function<double(int, int)>& cost);

// Best partial assignment of `items` to distinct `slots` (either may be the larger):
// minimises the sum over items of cost(item, slot), an item left without a slot costing
// `unassigned` (so no item is given a slot that costs more). Exhaustive (depth first with
// pruning); meant for a few items and slots (a frame's beams and its candidate dots). Returns
// the slot per item, -1 for none.
std::vector<int> BestInjection(int items, int slots, const std::function<double(int, int)>& cost,
                               double unassigned);

// RMS distance between a board's detected corners and their projection through the PnP pose;
// -1 if none projects.
double ReprojectionRms(const geometry::CameraModel& camera, const geometry::Rigid3d& cam_from_board,
                       const std::vector<Eigen::Vector3d>& pts,
                       const std::vector<Eigen::Vector2d>& px);

// What a stage decided besides its product: the frames it dropped (with the reason), what it
// noted, and, when it could not go on, why (`error`; the driver then stops with SolveError,
// carrying everything dropped and noted so far).
struct StageLog {
  std::vector<DroppedFrame> dropped;
  std::vector<std::string> notes;
  std::string error;
};

// The beams of session.yaml by index (the solver's beam numbering: their order there).
struct BeamTable {
  std::vector<int> ids;           // session.yaml id per index
  std::vector<bool> is_estimate;  // role estimate (fitted) or validate (held out)
  std::map<int, int> index_of_id;
  int size() const { return static_cast<int>(ids.size()); }
  std::optional<int> IndexOf(int id) const;
};
BeamTable MakeBeamTable(const std::vector<dataset::BeamSpec>& beams);
// "session.yaml: frame <file> lists beam <id> which is not in beams".
std::string UnknownBeamError(const std::string& file, int id);

}  // namespace msmcal::solver
