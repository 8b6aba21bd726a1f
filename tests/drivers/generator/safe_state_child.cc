// Helper process for safe_state_test: applies the rig signals on the mock units given by
// `argv[1]` (config) `argv[2]` `argv[3]` (ports), installs the SafeStateGuard, prints "ready",
// then blocks reading stdin. It ends by a signal (the guard's watcher) or, at EOF on stdin, by
// returning from main (the guard's destructor).
#include <cstdio>
#include <iostream>
#include <string>

#include "drivers/generator/rig_generators.h"
#include "drivers/generator/safe_state.h"

int main(int argc, char** argv) {
  if (argc != 4) return 2;
  using namespace msmcal::gen;
  RigGeneratorConfig config = LoadRigGeneratorConfig(argv[1]);
  config.unit1.link.port = std::stoi(argv[2]);
  config.unit2.link.port = std::stoi(argv[3]);
  auto master = OpenKeysight33500(config.unit1);
  auto slave = OpenKeysight33500(config.unit2);
  RigGenerators rig(*master, *slave);
  SafeStateGuard guard([&] {
    if (!rig.SafeState()) SafeStateGuard::ReportUnconfirmed();
  });
  rig.Apply(PlanRigSignals(config.signals));
  std::cout << "ready" << std::endl;
  std::string line;
  while (std::getline(std::cin, line)) {
  }
  return 0;
}
