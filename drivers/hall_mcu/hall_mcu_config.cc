#include "drivers/hall_mcu/hall_mcu_config.h"

#include <yaml-cpp/yaml.h>

#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

namespace msmcal::hall_mcu {
namespace {

[[noreturn]] void Fail(const std::string& origin, const YAML::Node& node, const std::string& field,
                       const std::string& what) {
  const int line = node.Mark().line >= 0 ? node.Mark().line + 1 : 0;
  throw std::runtime_error(origin + ":" + std::to_string(line) + ": " + field + ": " + what);
}

void CheckKeys(const std::string& origin, const YAML::Node& map, const std::string& field,
               const std::set<std::string>& allowed) {
  if (!map.IsMap()) Fail(origin, map, field, "must be a mapping");
  for (const auto& kv : map) {
    const std::string k = kv.first.as<std::string>();
    if (!allowed.count(k)) Fail(origin, kv.first, field + "." + k, "unknown key");
  }
}

template <typename T>
void Read(const std::string& origin, const YAML::Node& map, const std::string& key,
          const std::string& field, T* out) {
  const YAML::Node n = map[key];
  if (!n) return;
  try {
    if constexpr (sizeof(T) == 1) {
      const int v = n.as<int>();
      if (v < 0 || v > 255) Fail(origin, n, field + "." + key, "must be in 0..255");
      *out = static_cast<T>(v);
    } else {
      *out = n.as<T>();
    }
  } catch (const YAML::Exception&) {
    Fail(origin, n, field + "." + key, "has the wrong type");
  }
}

}  // namespace

HallMcuConfig ParseHallMcuConfig(const std::string& yaml_text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(origin + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  const YAML::Node section = root.IsMap() ? root["hall_mcu"] : YAML::Node();
  if (!section) throw std::runtime_error(origin + ": hall_mcu: missing section");
  const std::string f = "hall_mcu";
  CheckKeys(origin, section, f,
            {"device", "baud_rate", "stall_timeout_ms", "command_timeout_ms", "rate_hz", "sensor"});
  HallMcuConfig c;
  Read(origin, section, "device", f, &c.link.device);
  Read(origin, section, "baud_rate", f, &c.link.baud_rate);
  Read(origin, section, "stall_timeout_ms", f, &c.link.stall_timeout_ms);
  Read(origin, section, "command_timeout_ms", f, &c.link.command_timeout_ms);
  Read(origin, section, "rate_hz", f, &c.rate_hz);
  if (std::string msg = c.link.Validate(); !msg.empty()) Fail(origin, section, f, msg);
  if (c.rate_hz == 0 || c.rate_hz > 5000) {
    Fail(origin, section["rate_hz"], f + ".rate_hz",
         "= " + std::to_string(c.rate_hz) + ": violated constraint 1 <= rate_hz <= 5000");
  }
  if (const YAML::Node s = section["sensor"]) {
    const std::string sf = f + ".sensor";
    CheckKeys(origin, s, sf, {"gain_sel", "res_x", "res_y", "res_z", "osr", "dig_filt"});
    Read(origin, s, "gain_sel", sf, &c.sensor.gain_sel);
    Read(origin, s, "res_x", sf, &c.sensor.res_x);
    Read(origin, s, "res_y", sf, &c.sensor.res_y);
    Read(origin, s, "res_z", sf, &c.sensor.res_z);
    Read(origin, s, "osr", sf, &c.sensor.osr);
    Read(origin, s, "dig_filt", sf, &c.sensor.dig_filt);
    if (std::string msg = c.sensor.Validate(); !msg.empty()) Fail(origin, s, sf, msg);
  }
  return c;
}

HallMcuConfig LoadHallMcuConfig(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot open");
  std::stringstream ss;
  ss << in.rdbuf();
  return ParseHallMcuConfig(ss.str(), file.string());
}

}  // namespace msmcal::hall_mcu
