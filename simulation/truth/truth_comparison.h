#pragma once
// The simulator's ground truth (truth/ of a simulated session folder, mocks/rig/truth_io.h) as the
// calibration report compares the results with it: mirror planes and poses per trigger in the
// solver's convention for {0}, the dots of the scan pattern, the Hall time offset, and the true
// pose trajectory against the Hall model's prediction.

#include <filesystem>
#include <memory>

#include "sessions/report/session_report.h"

namespace msmcal::simulation {

// The truth of `dir`, or null when it has no truth/mirror_planes.csv. Throws std::runtime_error
// naming the truth file that cannot be parsed.
std::unique_ptr<report::TruthComparison> OpenSimTruth(const std::filesystem::path& dir);

// OpenSimTruth as the report's TruthSource.
report::TruthSource SimTruthSource();

}  // namespace msmcal::simulation
