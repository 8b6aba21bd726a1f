#include "mocks/generator/vxi11_server.h"

// clang-format off
// Boost 1.74's Asio uses std::exchange without including <utility> under C++20.
#include <utility>
// clang-format on

#include <atomic>
#include <boost/asio.hpp>
#include <deque>
#include <list>
#include <stdexcept>
#include <thread>

#include "mocks/generator/vxi11_device.h"
#include "mocks/generator/vxi11_protocol.h"

namespace msmcal::sim {

namespace asio = boost::asio;
using asio::ip::tcp;
using asio::ip::udp;

struct Vxi11Server::Impl {
  // One TCP connection to one of the channels; io thread only.
  struct Session : std::enable_shared_from_this<Session> {
    Impl* server;
    Vxi11Channel channel;
    uint64_t id;
    tcp::socket socket;
    vxi11::RecordAssembler records{vxi11::kMaxWriteBytes + 4096};
    std::deque<std::string> tx;
    bool writing = false;
    bool closed = false;
    char buf[65536];

    Session(Impl* s, Vxi11Channel c, uint64_t i, tcp::socket sock)
        : server(s), channel(c), id(i), socket(std::move(sock)) {}

    void Close() {
      if (closed) return;
      closed = true;
      boost::system::error_code ignored;
      socket.shutdown(tcp::socket::shutdown_both, ignored);
      socket.close(ignored);
      server->device.ConnectionClosed(id);
    }

    void Read() {
      auto self = shared_from_this();
      socket.async_read_some(asio::buffer(buf), [self](boost::system::error_code ec, size_t n) {
        if (ec || self->closed) {
          self->Close();
          return;
        }
        try {
          self->records.Feed(std::string_view(self->buf, n));
        } catch (const vxi11::Vxi11DecodeError&) {
          self->Close();  // an oversized record: the stream cannot be resynchronised
          return;
        }
        while (std::optional<std::string> record = self->records.Next()) {
          std::optional<std::string> reply = self->server->Handle(self->channel, *record, self->id);
          if (reply) self->Send(vxi11::RecordMark(*reply));
        }
        self->Read();
      });
    }

    void Send(std::string bytes) {
      tx.push_back(std::move(bytes));
      WriteNext();
    }

    void WriteNext() {
      if (tx.empty() || closed || writing) return;
      writing = true;
      auto self = shared_from_this();
      asio::async_write(socket, asio::buffer(tx.front()),
                        [self](boost::system::error_code ec, size_t) {
                          self->writing = false;
                          self->tx.pop_front();
                          if (ec) {
                            self->Close();
                            return;
                          }
                          self->WriteNext();
                        });
    }
  };

  Vxi11ServerOptions options;
  Vxi11Device device;
  asio::io_context io;
  tcp::acceptor core{io}, abort{io}, pmap_tcp{io};
  udp::socket pmap_udp{io};
  udp::endpoint udp_peer;
  char udp_buf[65536];
  std::list<std::weak_ptr<Session>> sessions;
  uint64_t next_id = 1;
  int core_port = 0, abort_port = 0, pmap_port = -1;
  std::string pmap_error;
  std::atomic<uint64_t> calls{0};
  std::thread thread;
  bool running = false;

  Impl(Mock33520B& unit, Vxi11ServerOptions o) : options(o), device(unit, Vxi11DeviceOptions{}) {}

  std::optional<std::string> Handle(Vxi11Channel channel, std::string_view record, uint64_t id) {
    ++calls;
    return device.Handle(channel, record, id);
  }

  static boost::system::error_code Listen(tcp::acceptor& a, int port) {
    boost::system::error_code ec;
    const tcp::endpoint ep(asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port));
    a.open(ep.protocol(), ec);
    if (!ec) a.set_option(tcp::acceptor::reuse_address(true), ec);
    if (!ec) a.bind(ep, ec);
    if (!ec) a.listen(asio::socket_base::max_listen_connections, ec);
    if (ec) {
      boost::system::error_code ignored;
      a.close(ignored);
    }
    return ec;
  }

  void Accept(tcp::acceptor& a, Vxi11Channel channel) {
    a.async_accept([this, &a, channel](boost::system::error_code ec, tcp::socket socket) {
      if (ec) return;  // acceptor closed
      boost::system::error_code ignored;
      socket.set_option(tcp::no_delay(true), ignored);
      auto session = std::make_shared<Session>(this, channel, next_id++, std::move(socket));
      sessions.remove_if([](const std::weak_ptr<Session>& w) { return w.expired(); });
      sessions.push_back(session);
      session->Read();
      Accept(a, channel);
    });
  }

  void ReceiveUdp() {
    pmap_udp.async_receive_from(
        asio::buffer(udp_buf), udp_peer, [this](boost::system::error_code ec, size_t n) {
          if (ec == asio::error::operation_aborted || !pmap_udp.is_open()) return;
          if (!ec) {
            std::optional<std::string> reply =
                Handle(Vxi11Channel::kPortmapper, std::string_view(udp_buf, n), /*id=*/0);
            boost::system::error_code ignored;
            if (reply) pmap_udp.send_to(asio::buffer(*reply), udp_peer, 0, ignored);
          }
          ReceiveUdp();
        });
  }
};

Vxi11Server::Vxi11Server(Mock33520B& unit, Vxi11ServerOptions options)
    : impl_(std::make_unique<Impl>(unit, options)) {}

Vxi11Server::~Vxi11Server() { Stop(); }

void Vxi11Server::Start() {
  Impl& s = *impl_;
  if (s.running) return;
  auto fail = [](const char* what, int port, const boost::system::error_code& ec) {
    return std::runtime_error(std::string("mock generator VXI-11: cannot listen on 127.0.0.1:") +
                              std::to_string(port) + " (" + what + ", " + ec.message() + ")");
  };
  if (auto ec = Impl::Listen(s.core, s.options.core_port)) {
    throw fail("core channel", s.options.core_port, ec);
  }
  if (auto ec = Impl::Listen(s.abort, s.options.abort_port)) {
    boost::system::error_code ignored;
    s.core.close(ignored);
    throw fail("abort channel", s.options.abort_port, ec);
  }
  s.core_port = s.core.local_endpoint().port();
  s.abort_port = s.abort.local_endpoint().port();
  s.device.SetPorts(static_cast<uint32_t>(s.core_port), static_cast<uint32_t>(s.abort_port));
  if (s.options.portmapper_port >= 0) {
    const int port = s.options.portmapper_port;
    boost::system::error_code ec = Impl::Listen(s.pmap_tcp, port);
    if (!ec) {
      const udp::endpoint ep(asio::ip::make_address("127.0.0.1"),
                             static_cast<unsigned short>(s.pmap_tcp.local_endpoint().port()));
      s.pmap_udp.open(ep.protocol(), ec);
      if (!ec) s.pmap_udp.bind(ep, ec);
      if (ec) {
        boost::system::error_code ignored;
        s.pmap_udp.close(ignored);
        s.pmap_tcp.close(ignored);
      }
    }
    if (ec) {
      s.pmap_error = "cannot bind the portmapper on 127.0.0.1:" + std::to_string(port) + " (" +
                     ec.message() +
                     "): VXI-11 discovery (lxi scpi -a HOST, TCPIP::HOST::INSTR) needs port "
                     "111 (root, or run in `unshare -rn`); serving the core channel alone on "
                     "port " +
                     std::to_string(s.core_port);
    } else {
      s.pmap_port = s.pmap_tcp.local_endpoint().port();
      s.Accept(s.pmap_tcp, Vxi11Channel::kPortmapper);
      s.ReceiveUdp();
    }
  }
  s.Accept(s.core, Vxi11Channel::kCore);
  s.Accept(s.abort, Vxi11Channel::kAbort);
  s.running = true;
  s.thread = std::thread([&s] { s.io.run(); });
}

void Vxi11Server::Stop() {
  Impl& s = *impl_;
  if (!s.running) return;
  asio::post(s.io, [&s] {
    boost::system::error_code ignored;
    s.core.close(ignored);
    s.abort.close(ignored);
    s.pmap_tcp.close(ignored);
    s.pmap_udp.close(ignored);
    for (auto& w : s.sessions) {
      if (auto p = w.lock()) p->Close();
    }
    s.io.stop();
  });
  s.thread.join();
  s.running = false;
}

int Vxi11Server::core_port() const { return impl_->core_port; }
int Vxi11Server::abort_port() const { return impl_->abort_port; }
int Vxi11Server::portmapper_port() const { return impl_->pmap_port; }
const std::string& Vxi11Server::portmapper_error() const { return impl_->pmap_error; }
uint64_t Vxi11Server::Calls() const { return impl_->calls; }

}  // namespace msmcal::sim
