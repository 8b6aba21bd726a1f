#pragma once
// The `hall_mcu:` section of the rig configuration (config/rig.yaml): the serial link and the
// sensor settings the recorder applies before streaming.
//
//   hall_mcu:
//     device: /dev/ttyACM0
//     baud_rate: 921600
//     stall_timeout_ms: 500
//     command_timeout_ms: 1000
//     rate_hz: 1000
//     sensor: {gain_sel: 7, res_x: 0, res_y: 0, res_z: 0, osr: 0, dig_filt: 0}
//
// Every key is optional (defaults as in HallMcuOptions / SensorSettings); unknown keys, bad types
// and values that fail Validate() throw std::runtime_error naming the file, line and field.

#include <cstdint>
#include <filesystem>
#include <string>

#include "drivers/hall_mcu/hall_sensor.h"

namespace msmcal::hall_mcu {

struct HallMcuConfig {
  HallMcuOptions link;
  uint16_t rate_hz = 1000;
  SensorSettings sensor;
};

// `origin` names the text in messages (usually the file path). Throws if the document has no
// `hall_mcu` section.
HallMcuConfig ParseHallMcuConfig(const std::string& yaml_text, const std::string& origin);
HallMcuConfig LoadHallMcuConfig(const std::filesystem::path& file);

}  // namespace msmcal::hall_mcu
