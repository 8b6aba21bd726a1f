#include "drivers/hall_mcu/hall_mcu_config.h"

#include <yaml-cpp/yaml.h>

#include <set>
#include <stdexcept>

#include "common/file_text.h"
#include "common/yaml_fields.h"

namespace msmcal::hall_mcu {
namespace {

// Reads map[key] into *out when present ("has the wrong type"; bytes in 0..255).
template <typename T>
void Read(const common::YamlFields& r, const YAML::Node& map, const std::string& key,
          const std::string& field, T* out) {
  const YAML::Node n = map[key];
  if (!n) return;
  try {
    if constexpr (sizeof(T) == 1) {
      const int v = n.as<int>();
      if (v < 0 || v > 255) r.Fail(n, field + "." + key, "must be in 0..255");
      *out = static_cast<T>(v);
    } else {
      *out = n.as<T>();
    }
  } catch (const YAML::Exception&) {
    r.Fail(n, field + "." + key, "has the wrong type");
  }
}

}  // namespace

HallMcuConfig ParseHallMcuConfig(const std::string& yaml_text, const std::string& origin) {
  const common::YamlFields r(origin);
  const YAML::Node root = r.Load(yaml_text);
  const YAML::Node section = root.IsMap() ? root["hall_mcu"] : YAML::Node();
  if (!section) throw std::runtime_error(origin + ": hall_mcu: missing section");
  const std::string f = "hall_mcu";
  r.CheckKeys(
      section, f,
      {"device", "baud_rate", "stall_timeout_ms", "command_timeout_ms", "rate_hz", "sensor"});
  HallMcuConfig c;
  Read(r, section, "device", f, &c.link.device);
  Read(r, section, "baud_rate", f, &c.link.baud_rate);
  Read(r, section, "stall_timeout_ms", f, &c.link.stall_timeout_ms);
  Read(r, section, "command_timeout_ms", f, &c.link.command_timeout_ms);
  Read(r, section, "rate_hz", f, &c.rate_hz);
  if (std::string msg = c.link.Validate(); !msg.empty()) r.Fail(section, f, msg);
  if (c.rate_hz == 0 || c.rate_hz > 5000) {
    r.Fail(section["rate_hz"], f + ".rate_hz",
           "= " + std::to_string(c.rate_hz) + ": violated constraint 1 <= rate_hz <= 5000");
  }
  if (const YAML::Node s = section["sensor"]) {
    const std::string sf = f + ".sensor";
    r.CheckKeys(s, sf, {"gain_sel", "res_x", "res_y", "res_z", "osr", "dig_filt"});
    Read(r, s, "gain_sel", sf, &c.sensor.gain_sel);
    Read(r, s, "res_x", sf, &c.sensor.res_x);
    Read(r, s, "res_y", sf, &c.sensor.res_y);
    Read(r, s, "res_z", sf, &c.sensor.res_z);
    Read(r, s, "osr", sf, &c.sensor.osr);
    Read(r, s, "dig_filt", sf, &c.sensor.dig_filt);
    if (std::string msg = c.sensor.Validate(); !msg.empty()) r.Fail(s, sf, msg);
  }
  return c;
}

HallMcuConfig LoadHallMcuConfig(const std::filesystem::path& file) {
  return ParseHallMcuConfig(common::ReadFileText(file), file.string());
}

}  // namespace msmcal::hall_mcu
