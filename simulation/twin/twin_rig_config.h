#pragma once
// What the twin takes from a lab's rig file (config/rig.yaml): the ports of the two generators
// (generators.unit1/unit2, 127.0.0.1 only), the drive design (generators.signals.drive: the
// world's default mirror drive, so the truth's pattern period is the rig's), the camera's GigE
// address and sensor size (camera:), the Hall MCU's device path and rate (hall_mcu:), and, when
// present, the beams (count, held-out ids). Everything else of the world (mirror position,
// camera poses C1/C2, sliding-plate design, Hall sensor model, noise) is the simulator's
// (config/sim.yaml defaults, or `sim`).
//
// Until sessions/rig's LoadRigFile is merged, the generator and Hall MCU sections are read by
// their own loaders and the camera:/beams: sections here, tolerantly (unknown keys ignored; the
// rig file's own loader validates the file).

#include <filesystem>
#include <string>

#include "mocks/rig/sim_options.h"
#include "simulation/twin/physical_twin.h"

namespace msmcal::twin {

// Throws std::runtime_error naming the file and field (the generators must be on 127.0.0.1 or
// localhost; camera.kind must be gige).
PhysicalTwinOptions TwinOptionsFromRigFile(const std::filesystem::path& rig_file,
                                           const sim::SimOptions& world);

}  // namespace msmcal::twin
