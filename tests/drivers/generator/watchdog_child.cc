// Helper process for watchdog_test, one binary in two roles (as msmcal is):
//   watchdog_child watchdog ARGS...       the watchdog itself (RunWatchdog)
//   watchdog_child drive CONFIG PORT1 PORT2 LOG
//       arms the watchdog (this binary, role `watchdog`) for the mock units on PORT1/PORT2 with
//       LOG as its log, installs the SafeStateGuard (whose confirmed safe state stands the
//       watchdog down), applies the rig signals (outputs on) through the real driver, prints
//       "ready <watchdog pid>", then blocks reading stdin; at EOF it returns from main (clean
//       exit: the guard's safe state, then the stand-down, then "watchdog exit <status>").
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "drivers/generator/rig_generators.h"
#include "drivers/generator/safe_state.h"
#include "drivers/generator/watchdog.h"

int main(int argc, char** argv) {
  using namespace msmcal::gen;
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (!args.empty() && args[0] == "watchdog") {
    try {
      return RunWatchdog(ParseWatchdogArguments({args.begin() + 1, args.end()}));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return kWatchdogUsage;
    }
  }
  if (args.size() != 5 || args[0] != "drive") return 2;
  RigGeneratorConfig config = LoadRigGeneratorConfig(args[1]);
  config.unit1.link.port = std::stoi(args[2]);
  config.unit2.link.port = std::stoi(args[3]);
  auto master = OpenKeysight33500(config.unit1);
  auto slave = OpenKeysight33500(config.unit2);
  RigGenerators rig(*master, *slave);
  std::unique_ptr<Watchdog> watchdog = Watchdog::Start(
      SelfWatchdogLaunch("watchdog_child", "watchdog"), WatchdogConfigFor(config, args[4]));
  SafeStateGuard guard([&] {
    if (rig.SafeState()) {
      std::cout << "watchdog exit " << watchdog->StandDown() << std::endl;
    } else {
      SafeStateGuard::ReportUnconfirmed();
    }
  });
  rig.Apply(PlanRigSignals(config.signals));
  std::cout << "ready " << watchdog->pid() << std::endl;
  std::string line;
  while (std::getline(std::cin, line)) {
  }
  return 0;
}
