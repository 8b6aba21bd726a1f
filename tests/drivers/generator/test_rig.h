#pragma once
// Shared fixture pieces: the example rig configuration pointed at a pair of mock units.

#include <cstdlib>
#include <string>

#include "drivers/generator/rig_config.h"
#include "mocks/generator/mock_server.h"

namespace msmcal::gen::testing {

inline std::string SourceDir() {
  const char* d = std::getenv("MSMCAL_SOURCE_DIR");
  return d ? d : MSMCAL_TEST_SOURCE_DIR;
}

// config/rig.yaml with the units' ports replaced by the mock pair's and short deadlines.
inline RigGeneratorConfig RigConfigFor(sim::MockGeneratorPair& pair, int io_timeout_ms = 2000) {
  RigGeneratorConfig c = LoadRigGeneratorConfig(SourceDir() + "/config/rig.yaml");
  c.unit1.link.port = pair.port(1);
  c.unit2.link.port = pair.port(2);
  c.unit1.link.io_timeout_ms = c.unit2.link.io_timeout_ms = io_timeout_ms;
  return c;
}

}  // namespace msmcal::gen::testing
