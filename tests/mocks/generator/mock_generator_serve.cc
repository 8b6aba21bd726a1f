// Serves one mock 33520B for the conformance scripts (the same behaviour as
// `msmcal mock generator --port P`, without linking the whole CLI): prints
// "listening on 127.0.0.1:P" once it accepts connections, serves until stdin closes.
#include <iostream>
#include <string>

#include "mocks/generator/mock_server.h"

int main(int argc, char** argv) {
  msmcal::sim::UnitOptions u;
  if (argc > 1) u.identity = argv[1];
  msmcal::sim::Mock33520B unit(u, nullptr);
  msmcal::sim::MockGeneratorServer server(unit, 0);
  server.Start();
  std::cout << "listening on 127.0.0.1:" << server.port() << std::endl;
  std::string line;
  while (std::getline(std::cin, line)) {
  }
  server.Stop();
  return 0;
}
