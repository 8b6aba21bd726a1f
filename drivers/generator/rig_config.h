#pragma once
// The generator part of the rig configuration (config/rig.yaml, section `generators:` and
// `signals:`): YAML -> options structs -> Validate(), all before any connection is made.

#include <string>

#include "drivers/generator/function_generator.h"
#include "processing/signal/rig_signals.h"

namespace msmcal::gen {

// Levels of a logic-like output (laser trigger input, MCU clock input), volts into the load.
struct LogicLevels {
  double low_v = 0.0;
  double high_v = 5.0;
  double load_ohm = kHighZ;
};

struct RigSignalsConfig {
  signal::SineDrive fast;  // generator 1 channel 1
  signal::SineDrive slow;  // generator 1 channel 2
  double coil_load_ohm = 50.0;
  LogicLevels laser;  // generator 2 channel 1 (trigger arb)
  LogicLevels clock;  // generator 2 channel 2 (square, rising edge at pattern phase 0)
  signal::TriggerDesignOptions trigger;
};

// Highest duty a laser trigger limit (generator 2 channel 1, signals.trigger.max_duty) may allow.
inline constexpr double kMaxLaserDuty = 0.1;

struct RigGeneratorConfig {
  Keysight33500Options unit1;  // master: drives, 10 MHz out, trigger out
  Keysight33500Options unit2;  // slave: laser trigger and clock, external reference and trigger
  RigSignalsConfig signals;
  // Checks every field (finite, inside what a 33520B delivers into the configured loads, one
  // role per channel, laser duty limits <= kMaxLaserDuty) and that the designed signals respect
  // the channel limits. Empty when valid; otherwise names the field, its value and the
  // constraint.
  std::string Validate() const;
};

// Reads `path`. Throws std::runtime_error naming the file, the line and the field for missing or
// malformed entries; unknown keys are refused as well (a typo must not silently fall back to a
// default). Does not validate: call Validate().
RigGeneratorConfig LoadRigGeneratorConfig(const std::string& path);
// Same from YAML text (`origin` names it in messages).
RigGeneratorConfig ParseRigGeneratorConfig(const std::string& yaml_text, const std::string& origin);

}  // namespace msmcal::gen
