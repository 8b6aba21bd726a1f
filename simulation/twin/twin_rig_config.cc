#include "simulation/twin/twin_rig_config.h"

#include <cmath>
#include <stdexcept>

namespace msmcal::twin {

PhysicalTwinOptions TwinOptionsFromRigFile(const std::filesystem::path& rig_file,
                                           const sim::SimOptions& world) {
  return TwinOptionsFromRig(rig::LoadRigFile(rig_file), world);
}

PhysicalTwinOptions TwinOptionsFromRig(const rig::RigFile& r, const sim::SimOptions& world) {
  const std::string& origin = r.origin;
  PhysicalTwinOptions o;
  o.sim = world;
  const gen::RigGeneratorConfig& g = r.generators;
  for (const auto* unit : {&g.unit1, &g.unit2}) {
    if (unit->link.host != "127.0.0.1" && unit->link.host != "localhost")
      throw std::runtime_error(origin + ": generators." + unit->name + ".host = " +
                               unit->link.host + ": the twin serves on 127.0.0.1 only");
  }
  o.port1 = g.unit1.link.port;
  o.port2 = g.unit2.link.port;
  auto drive = [](const signal::SineDrive& d, sim::AxisOptions* a) {
    a->frequency_hz = d.frequency_hz;
    a->amplitude_vpp = d.amplitude_vpp;
    a->phase_deg = d.phase_deg;
  };
  drive(g.signals.fast, &o.sim.mirror.fast);
  drive(g.signals.slow, &o.sim.mirror.slow);

  if (r.camera.kind != rig::CameraKind::kGige)
    throw std::runtime_error(origin + ": camera.kind = " + rig::ToString(r.camera.kind) +
                             ": the twin serves a GigE Vision camera only");
  o.camera_address = r.camera.address;
  o.camera_frame_rate_hz = r.camera.frame_rate_hz;
  const geometry::CameraModel& m = r.camera.model;
  auto& c = o.sim.camera;
  c.width = m.width;
  c.height = m.height;
  c.fx = m.fx;
  c.fy = m.fy;
  c.cx = m.cx;
  c.cy = m.cy;
  c.distortion = m.distortion;

  o.sim.world_board = {r.world_board.cols, r.world_board.rows, r.world_board.square_mm};
  o.sim.sliding_board = {r.sliding_board.cols, r.sliding_board.rows, r.sliding_board.square_mm};

  auto& b = o.sim.beams;
  if (r.beams.count != b.count) {
    // More or fewer beams than the world's: fan positions and mirror offsets spread evenly.
    const int n = r.beams.count;
    b.fan_fractions.clear();
    b.offsets_mm.clear();
    for (int k = 0; k < n; ++k) {
      b.fan_fractions.push_back(-0.5 + static_cast<double>(k) / (n - 1));
      b.offsets_mm.push_back({1.2 * std::cos(2.1 * k), 1.2 * std::sin(2.1 * k)});
    }
    b.count = n;
  }
  b.validate_ids = r.beams.validate_ids;

  o.sim.step1.poses = r.sliding_plate.poses;
  o.sim.step1.nearest_mm = r.sliding_plate.nearest_mm;
  o.sim.step1.farthest_mm = r.sliding_plate.farthest_mm;
  o.sim.step1.tilt_deg = r.sliding_plate.tilt_deg;

  o.hall_link_path = r.hall_mcu.link.device;
  o.hall_rate_hz = r.hall_mcu.rate_hz;
  o.sim.hall.sample_rate_hz = r.hall_mcu.rate_hz;
  if (std::string e = o.sim.Validate(); !e.empty())
    throw std::runtime_error(origin + ": the twin's world with this rig file: " + e);
  return o;
}

}  // namespace msmcal::twin
