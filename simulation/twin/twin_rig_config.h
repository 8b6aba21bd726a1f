#pragma once
// What the twin takes from a lab's rig file (sessions/rig LoadRigFile, docs/rig-file.md): the
// ports of the two generators (127.0.0.1 only), the drive design (generators.signals.drive: the
// world's default mirror drive, so the truth's pattern period is the rig's), the camera's GigE
// address, frame rate, sensor size and intrinsics, the Hall MCU's device path and rate, the
// boards, the beams (count, held-out ids) and the sliding plate's pose design. Everything else
// of the world (mirror position, camera poses C1/C2, Hall sensor model, noise) is the
// simulator's (config/sim.yaml defaults, or `world`).

#include <filesystem>
#include <string>

#include "mocks/rig/sim_options.h"
#include "sessions/rig/rig_file.h"
#include "simulation/twin/physical_twin.h"

namespace msmcal::twin {

// Throws std::runtime_error naming the file and field (LoadRigFile's refusals; the generators
// must be on 127.0.0.1 or localhost; the camera must be kind gige; the resulting world must
// validate). The exposure is left at PhysicalTwinOptions' default (see docs/twin.md).
PhysicalTwinOptions TwinOptionsFromRigFile(const std::filesystem::path& rig_file,
                                           const sim::SimOptions& world);
PhysicalTwinOptions TwinOptionsFromRig(const rig::RigFile& rig, const sim::SimOptions& world);

}  // namespace msmcal::twin
