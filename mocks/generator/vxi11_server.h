#pragma once
// VXI-11 front of a Mock33520B on 127.0.0.1: the core channel (DEVICE_CORE 0x0607AF), the abort
// channel (DEVICE_ASYNC 0x0607B0) and, when its port can be bound, a portmapper (program 100000
// version 2: NULL and GETPORT, over TCP and UDP) that maps both to their ports, as a 33520B's LAN
// interface does. Clients that find the instrument by its host name alone (`lxi scpi -a HOST`,
// pyvisa's TCPIP::HOST::INSTR) ask the portmapper on port 111: binding it needs root or a user
// namespace (`unshare -rn`); without it the core channel is still served on its own port.
// Protocol details and the mock's simplifications: vxi11_device.h.
// Threads: one I/O thread; Start()/Stop() from any one thread.

#include <cstdint>
#include <memory>
#include <string>

#include "mocks/generator/mock_33520b.h"

namespace msmcal::sim {

struct Vxi11ServerOptions {
  int core_port = 0;          // 0: any free port
  int abort_port = 0;         // 0: any free port
  int portmapper_port = 111;  // -1: no portmapper
};

class Vxi11Server {
 public:
  Vxi11Server(Mock33520B& unit, Vxi11ServerOptions options);
  ~Vxi11Server();
  Vxi11Server(const Vxi11Server&) = delete;
  Vxi11Server& operator=(const Vxi11Server&) = delete;

  // Binds the channels and starts serving. Throws std::runtime_error naming the port when the
  // core or abort channel cannot be bound; a portmapper port that cannot be bound is not an
  // error: portmapper_port() is then -1 and portmapper_error() says why.
  void Start();
  void Stop();
  int core_port() const;
  int abort_port() const;
  int portmapper_port() const;
  const std::string& portmapper_error() const;
  uint64_t Calls() const;  // RPC calls handled (all channels)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace msmcal::sim
