// libFuzzer target: config/rig.yaml, its readers: the generator part (ParseRigGeneratorConfig),
// the Hall MCU part (ParseHallMcuConfig) and the whole rig file (rig::ParseRigFile, which runs
// both and validates every other section).
//
// Checks: each reader returns or throws std::runtime_error naming the file ("rig.yaml:LINE");
// Validate() of an accepted generator configuration returns (empty or a message) without
// throwing: ParseRigFile calls it first thing after ParseRigGeneratorConfig and turns a message
// into the file's error (it is not called a second time here: planning the signals walks up to
// 1 M waveform samples and was most of an execution's time).
#include <cstdint>
#include <string>

#include "drivers/generator/rig_config.h"
#include "drivers/hall_mcu/hall_mcu_config.h"
#include "fuzz/fuzz_util.h"
#include "sessions/rig/rig_file.h"

using namespace msmcal;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text = fuzz::Text(data, size);
  fuzz::Returns([&] { (void)gen::ParseRigGeneratorConfig(text, "rig.yaml"); }, "rig.yaml");
  fuzz::Returns([&] { (void)hall_mcu::ParseHallMcuConfig(text, "rig.yaml"); }, "rig.yaml");
  fuzz::Returns([&] { (void)rig::ParseRigFile(text, "rig.yaml"); }, "rig.yaml");
  return 0;
}
