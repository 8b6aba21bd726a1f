#include "simulation/twin/twin_rig_config.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <stdexcept>

#include "drivers/generator/rig_config.h"
#include "drivers/hall_mcu/hall_mcu_config.h"

namespace msmcal::twin {

PhysicalTwinOptions TwinOptionsFromRigFile(const std::filesystem::path& rig_file,
                                           const sim::SimOptions& world) {
  const std::string origin = rig_file.string();
  PhysicalTwinOptions o;
  o.sim = world;
  const gen::RigGeneratorConfig g = gen::LoadRigGeneratorConfig(origin);
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

  YAML::Node doc;
  try {
    doc = YAML::LoadFile(origin);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(origin + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  auto field = [&](const YAML::Node& n, const std::string& name) {
    return origin + ":" + std::to_string(n.Mark().line + 1) + ": " + name;
  };
  try {
    if (const YAML::Node cam = doc["camera"]) {
      if (cam["kind"] && cam["kind"].as<std::string>() != "gige")
        throw std::runtime_error(field(cam["kind"], "camera.kind") + " = " +
                                 cam["kind"].as<std::string>() +
                                 ": the twin serves a GigE Vision camera only");
      if (cam["address"]) o.camera_address = cam["address"].as<std::string>();
      if (cam["frame_rate_hz"]) o.camera_frame_rate_hz = cam["frame_rate_hz"].as<double>();
      auto& c = o.sim.camera;
      const int w0 = c.width;
      if (cam["width"]) c.width = cam["width"].as<int>();
      if (cam["height"]) c.height = cam["height"].as<int>();
      // A different sensor size keeps the field of view unless the intrinsics are given.
      const double scale = static_cast<double>(c.width) / w0;
      c.fx = cam["fx"] ? cam["fx"].as<double>() : c.fx * scale;
      c.fy = cam["fy"] ? cam["fy"].as<double>() : c.fy * scale;
      c.cx = cam["cx"] ? cam["cx"].as<double>() : 0.5 * (c.width - 1);
      c.cy = cam["cy"] ? cam["cy"].as<double>() : 0.5 * (c.height - 1);
    }
    if (const YAML::Node beams = doc["beams"]) {
      if (beams["count"]) {
        const int n = beams["count"].as<int>();
        auto& b = o.sim.beams;
        if (n != b.count) {
          // More or fewer beams than the world's: fan fractions and offsets spread evenly.
          b.fan_fractions.clear();
          b.offsets_mm.clear();
          for (int k = 0; k < n; ++k) {
            b.fan_fractions.push_back(n == 1 ? 0.0 : -0.5 + static_cast<double>(k) / (n - 1));
            b.offsets_mm.push_back({0.8 * std::cos(2.1 * k), 0.8 * std::sin(2.1 * k)});
          }
          b.count = n;
        }
      }
      if (beams["validate_ids"]) o.sim.beams.validate_ids = beams["validate_ids"].as<std::vector<int>>();
    }
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(origin + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  if (doc["hall_mcu"]) {
    const hall_mcu::HallMcuConfig h = hall_mcu::LoadHallMcuConfig(rig_file);
    o.hall_link_path = h.link.device;
    o.hall_rate_hz = h.rate_hz;
    o.sim.hall.sample_rate_hz = h.rate_hz;
  }
  if (std::string e = o.sim.Validate(); !e.empty())
    throw std::runtime_error(origin + ": the twin's world with this rig file: " + e);
  return o;
}

}  // namespace msmcal::twin
