// Serves one mock 33520B for the conformance scripts (the same behaviour as
// `msmcal mock generator --port P [--vxi11]`, without linking the whole CLI):
//   mock_generator_serve [IDN [--vxi11 PORTMAPPER_PORT]]
// prints "listening on 127.0.0.1:P" once it accepts raw SCPI connections, with --vxi11 then
// "vxi11 core 127.0.0.1:C abort 127.0.0.1:A portmapper 127.0.0.1:M" (M = -1 when the portmapper
// port could not be bound, followed by the reason on stderr), and serves until stdin closes.
#include <iostream>
#include <memory>
#include <string>

#include "mocks/generator/mock_server.h"
#include "mocks/generator/vxi11_server.h"

int main(int argc, char** argv) {
  msmcal::sim::UnitOptions u;
  if (argc > 1) u.identity = argv[1];
  msmcal::sim::Mock33520B unit(u, nullptr);
  msmcal::sim::MockGeneratorServer server(unit, 0);
  server.Start();
  std::cout << "listening on 127.0.0.1:" << server.port() << std::endl;
  std::unique_ptr<msmcal::sim::Vxi11Server> vxi11;
  if (argc > 3 && std::string(argv[2]) == "--vxi11") {
    msmcal::sim::Vxi11ServerOptions o;
    o.portmapper_port = std::stoi(argv[3]);
    vxi11 = std::make_unique<msmcal::sim::Vxi11Server>(unit, o);
    vxi11->Start();
    if (!vxi11->portmapper_error().empty()) std::cerr << vxi11->portmapper_error() << std::endl;
    std::cout << "vxi11 core 127.0.0.1:" << vxi11->core_port()
              << " abort 127.0.0.1:" << vxi11->abort_port()
              << " portmapper 127.0.0.1:" << vxi11->portmapper_port() << std::endl;
  }
  std::string line;
  while (std::getline(std::cin, line)) {
  }
  if (vxi11) vxi11->Stop();
  server.Stop();
  return 0;
}
