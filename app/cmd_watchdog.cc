// The hidden subcommand `msmcal watchdog ...`: the watchdog process (drivers/generator/watchdog.h,
// docs/watchdog.md). msmcal starts it as itself (Watchdog::Start with SelfWatchdogLaunch) before
// the first generator output goes on; it is not meant to be typed, so `--help` does not list it.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "app/command_registry.h"
#include "drivers/generator/watchdog.h"

namespace {

void AddWatchdogCommand(CLI::App& app) {
  auto* wd = app.add_subcommand("watchdog", "Generator watchdog process (started by msmcal)");
  wd->group("");         // hidden
  wd->prefix_command();  // every argument after `watchdog` is the watchdog's
  wd->callback([wd] {
    int status = msmcal::gen::kWatchdogUsage;
    try {
      status = msmcal::gen::RunWatchdog(msmcal::gen::ParseWatchdogArguments(wd->remaining()));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "msmcal %s\n", e.what());
    }
    if (status != 0) throw CLI::RuntimeError(status);
  });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/99, AddWatchdogCommand);
