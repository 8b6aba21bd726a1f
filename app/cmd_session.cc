// `msmcal session check --rig FILE --camera ADDR [--mcu DEVICE]`: the orchestrator's rig check
// against the instruments of a rig configuration (config/rig.yaml: `generators:` and `hall_mcu:`
// sections): identifies both generators and checks the reference lock and the signal limits,
// opens the camera by address (Mono8), identifies the Hall MCU and reads a status frame. Prints
// what it found and, when something is wrong, the list of problems (exit status 1). Generator
// outputs are left off.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <memory>
#include <string>

#include "app/command_registry.h"
#include "drivers/generator/rig_config.h"
#include "drivers/hall_mcu/hall_mcu_config.h"
#include "sessions/orchestrator/orchestrator.h"

namespace msmcal::app {
namespace {

struct SessionCheckArgs {
  std::string rig = "config/rig.yaml";
  std::string camera;
  std::string mcu;
};

void RunSessionCheck(const SessionCheckArgs& args) {
  orchestrator::OrchestratorOptions options;
  options.out_dir = "unused";
  options.generators = gen::LoadRigGeneratorConfig(args.rig);
  if (std::string e = options.generators.Validate(); !e.empty())
    throw std::runtime_error(args.rig + ": " + e);
  const hall_mcu::HallMcuConfig mcu = hall_mcu::LoadHallMcuConfig(args.rig);
  options.mcu = mcu.link;
  options.mcu_rate_hz = mcu.rate_hz;
  options.camera_address = args.camera;
  const std::string device = args.mcu.empty() ? mcu.link.device : args.mcu;
  const orchestrator::RigCheckResult r = orchestrator::CheckRigOnly(options, nullptr, device);
  for (const auto& f : r.found) std::printf("ok: %s\n", f.c_str());
  if (!r.ok) {
    std::printf("rig check FAILED (%zu problems):\n", r.problems.size());
    for (const auto& p : r.problems) std::printf("  - %s\n", p.c_str());
    throw CLI::RuntimeError(1);
  }
  std::printf("rig check passed; generator outputs are off\n");
}

void AddSessionCommands(CLI::App& app) {
  CLI::App* session = GetOrAddSubcommand(app, "session", "Calibration sessions on the rig");
  auto args = std::make_shared<SessionCheckArgs>();
  auto* check = session->add_subcommand(
      "check", "Rig check: identify every instrument, generator lock, camera format, MCU stream");
  check->add_option("--rig", args->rig, "Rig configuration (generators:, hall_mcu:)");
  check->add_option("--camera", args->camera, "Camera IP address (GigE Vision, opened by address)")
      ->required();
  check->add_option("--mcu", args->mcu, "Hall MCU serial device (default: the rig file's)");
  check->callback([args] { RunSessionCheck(*args); });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/6, AddSessionCommands);

}  // namespace msmcal::app
