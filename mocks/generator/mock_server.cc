#include "mocks/generator/mock_server.h"

// clang-format off
// Boost 1.74's Asio uses std::exchange without including <utility> under C++20.
#include <utility>
// clang-format on

#include <algorithm>
#include <boost/asio.hpp>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <list>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <vector>

#include "mocks/generator/scpi_parser.h"

namespace msmcal::sim {

namespace asio = boost::asio;
using asio::ip::tcp;

struct MockGeneratorServer::Impl {
  // One connection; every member is used on the io thread only.
  struct Session : std::enable_shared_from_this<Session> {
    Impl* server;
    tcp::socket socket;
    std::string rx;            // received bytes; rx[0, message_start) are consumed
    size_t message_start = 0;  // start of the message being framed
    MessageFramer framer;
    bool discarding = false;                      // the current message overran the input buffer
    std::deque<std::pair<std::string, bool>> tx;  // bytes, close after
    size_t pending = 0;                           // bytes in tx
    bool reading = false;                         // an async_read_some is outstanding
    bool writing = false;                         // an async_write is outstanding
    char buf[65536];
    bool closed = false;
    bool served = false;    // counted in Impl::served_open (SecondConnection)
    bool frozen = false;    // FaultKind::kFreeze: read and ignore everything
    bool delaying = false;  // a reply held for a time (FaultKind::kDelayReply with delay_ms)
    asio::steady_timer delay_timer;

    Session(Impl* s, tcp::socket sock)
        : server(s), socket(std::move(sock)), delay_timer(server->io) {}

    void Close() {
      if (closed) return;
      closed = true;
      boost::system::error_code ignored;
      socket.shutdown(tcp::socket::shutdown_both, ignored);
      socket.close(ignored);
      delay_timer.cancel();
      server->OnClosed(*this);
    }

    // A held reply stalls the connection as a slow instrument does: later messages wait for it.
    bool Blocked() const { return delaying || pending > server->limits.max_pending_reply_bytes; }

    // Reads unless the unsent replies are over the cap (back-pressure: the client's sends
    // block in TCP until it reads its replies).
    void MaybeRead() {
      if (closed || reading) return;
      if (Blocked()) {
        server->UpdateStats([](ServerStats& st) { ++st.read_pauses; });
        return;
      }
      reading = true;
      auto self = shared_from_this();
      socket.async_read_some(asio::buffer(buf), [self](boost::system::error_code ec, size_t n) {
        self->reading = false;
        if (ec) {
          self->Close();
          return;
        }
        self->rx.append(self->buf, n);
        const size_t held = self->rx.size() - self->message_start;
        self->server->UpdateStats(
            [held](ServerStats& st) { st.input_high_water = std::max(st.input_high_water, held); });
        self->Drain();
        self->MaybeRead();
      });
    }

    // Hands complete messages to the unit while the reply cap allows; each byte is framed once.
    void Drain() {
      while (!closed && !Blocked()) {
        const auto end = framer.Next(rx);
        const size_t length = (end ? *end : framer.scanned()) - message_start;
        if (!discarding && length > server->limits.max_message_bytes) {
          discarding = true;
          server->unit.ReportInputOverrun();
          server->UpdateStats([](ServerStats& st) { ++st.input_overruns; });
        }
        if (!end) {
          if (discarding) message_start = framer.scanned();  // drop what was framed
          break;
        }
        const size_t start = message_start;
        message_start = *end + 1;
        framer.Reset(message_start);
        if (discarding) {
          discarding = false;
          continue;
        }
        std::string message = rx.substr(start, *end - start);
        server->UpdateStats([](ServerStats& st) { ++st.messages; });
        Handle(message);
      }
      // Compact once per call, so consuming k messages of one read costs O(bytes), not O(k^2).
      if (message_start > 0) {
        rx.erase(0, message_start);
        framer.Shift(message_start);
        message_start = 0;
      }
    }

    void Handle(const std::string& message) {
      if (frozen) return;
      if (std::optional<Fault> f = server->TakeFault(message, /*reply=*/false)) {
        server->UpdateStats([](ServerStats& st) { ++st.faults_applied; });
        if (f->kind == FaultKind::kDropConnection) {
          Close();
        } else {
          frozen = true;
        }
        return;
      }
      std::string reply = server->unit.Process(message);
      if (reply.empty()) return;
      reply.push_back('\n');
      std::optional<Fault> fault = server->TakeFault(message, /*reply=*/true);
      if (fault) server->UpdateStats([](ServerStats& st) { ++st.faults_applied; });
      if (!fault) {
        Send(std::move(reply), false);
      } else if (fault->kind == FaultKind::kDelayReply && fault->delay_ms >= 0) {
        delaying = true;
        delay_timer.expires_after(std::chrono::milliseconds(fault->delay_ms));
        auto self = shared_from_this();
        delay_timer.async_wait([self, reply = std::move(reply)](boost::system::error_code ec) {
          self->delaying = false;
          if (ec || self->closed) return;
          self->Send(reply, false);
          self->Drain();
          self->MaybeRead();
        });
      } else if (fault->kind == FaultKind::kDelayReply) {
        std::lock_guard lock(server->mu);
        server->held.emplace_back(weak_from_this(), std::move(reply));
      } else if (fault->kind == FaultKind::kDropMidReply) {
        Send(reply.substr(0, reply.size() / 2), true);
      } else {
        Send(std::string("\x01\xfe\xff\x7fGARBAGE\x00\x1b[0m\n", 17), false);
      }
    }

    void Send(std::string bytes, bool close_after) {
      pending += bytes.size();
      const size_t p = pending;
      server->UpdateStats([p](ServerStats& st) {
        st.pending_reply_high_water = std::max(st.pending_reply_high_water, p);
      });
      tx.emplace_back(std::move(bytes), close_after);
      WriteNext();
    }

    // Writes every queued reply (up to one that closes the connection) in one gather write.
    void WriteNext() {
      if (tx.empty() || closed || writing) return;
      std::vector<asio::const_buffer> bufs;
      size_t count = 0;
      bool close_after = false;
      for (const auto& [bytes, close] : tx) {
        bufs.push_back(asio::buffer(bytes));
        ++count;
        if ((close_after = close)) break;
      }
      writing = true;
      auto self = shared_from_this();
      asio::async_write(socket, bufs,
                        [self, count, close_after](boost::system::error_code ec, size_t n) {
                          self->writing = false;
                          self->pending -= n;
                          for (size_t i = 0; i < count; ++i) self->tx.pop_front();
                          if (ec || close_after) {
                            self->Close();
                            return;
                          }
                          // Replies drained to half the cap: serve what is buffered, read on.
                          if (!self->reading &&
                              self->pending <= self->server->limits.max_pending_reply_bytes / 2) {
                            self->Drain();
                            self->MaybeRead();
                          }
                          self->WriteNext();
                        });
    }
  };

  Mock33520B& unit;
  int requested_port;
  ServerLimits limits;
  mutable std::mutex stats_mu;
  mutable std::condition_variable stats_cv;
  ServerStats stats;
  int bound_port = 0;
  asio::io_context io;
  tcp::acceptor acceptor{io};
  std::thread thread;
  std::list<std::weak_ptr<Session>> sessions;  // io thread only
  std::mutex mu;                               // faults, held
  std::deque<Fault> faults;
  std::vector<std::pair<std::weak_ptr<Session>, std::string>> held;
  std::atomic<uint64_t> accepted{0};
  bool running = false;
  // SecondConnection (io thread only): served connections open, and those waiting their turn
  // (owned here: no read is outstanding on them to keep them alive).
  int served_open = 0;
  std::deque<std::shared_ptr<Session>> waiting;

  Impl(Mock33520B& u, int port, ServerLimits l) : unit(u), requested_port(port), limits(l) {}

  template <typename F>
  void UpdateStats(F f) {
    {
      std::lock_guard lock(stats_mu);
      f(stats);
    }
    stats_cv.notify_all();
  }

  static bool IsMessageFault(FaultKind k) {
    return k == FaultKind::kDropConnection || k == FaultKind::kFreeze;
  }

  // The first queued fault of the category (`reply`: reply faults, else message faults) whose
  // match and skip count say it applies to `message`.
  std::optional<Fault> TakeFault(const std::string& message, bool reply) {
    std::lock_guard lock(mu);
    const std::string upper = Upper(message);
    for (auto it = faults.begin(); it != faults.end(); ++it) {
      if (IsMessageFault(it->kind) == reply) continue;
      if (it->match.empty() || upper.find(Upper(it->match)) != std::string::npos) {
        if (it->skip > 0) {
          --it->skip;
          return std::nullopt;
        }
        Fault f = *it;
        faults.erase(it);
        return f;
      }
    }
    return std::nullopt;
  }

  void Accept() {
    acceptor.async_accept([this](boost::system::error_code ec, tcp::socket socket) {
      if (ec) return;  // acceptor closed
      boost::system::error_code ignored;
      socket.set_option(tcp::no_delay(true), ignored);
      auto session = std::make_shared<Session>(this, std::move(socket));
      sessions.remove_if([](const std::weak_ptr<Session>& w) { return w.expired(); });
      sessions.push_back(session);
      ++accepted;
      UpdateStats([](ServerStats& st) { ++st.connections; });
      if (served_open == 0 || limits.second_connection == SecondConnection::kServe) {
        Serve(*session);
      } else if (limits.second_connection == SecondConnection::kQueue) {
        waiting.push_back(session);
      } else {
        UpdateStats([](ServerStats& st) { ++st.connections_turned_away; });
        session->Close();
      }
      Accept();
    });
  }

  void Serve(Session& session) {
    session.served = true;
    ++served_open;
    session.MaybeRead();
  }

  // A connection closed (either side): the next waiting one, if any, is served.
  void OnClosed(Session& session) {
    UpdateStats([](ServerStats& st) { ++st.connections_closed; });
    if (!session.served) return;
    session.served = false;
    --served_open;
    while (served_open == 0 && !waiting.empty()) {
      std::shared_ptr<Session> next = std::move(waiting.front());
      waiting.pop_front();
      if (!next->closed) Serve(*next);
    }
  }
};

Fault ParseFault(const std::string& text) {
  auto bad = [&](const std::string& why) {
    return std::invalid_argument("--fault '" + text + "': " + why +
                                 " (expected KIND[,after=N][,match=TEXT][,ms=MS], KIND one of "
                                 "drop, freeze, delay, garbage, drop-mid-reply)");
  };
  std::vector<std::string> parts;
  size_t start = 0;
  for (;;) {
    const size_t comma = text.find(',', start);
    parts.push_back(text.substr(start, comma == std::string::npos ? comma : comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  Fault f;
  const std::string& kind = parts[0];
  if (kind == "drop") {
    f.kind = FaultKind::kDropConnection;
  } else if (kind == "freeze") {
    f.kind = FaultKind::kFreeze;
  } else if (kind == "delay") {
    f.kind = FaultKind::kDelayReply;
  } else if (kind == "garbage") {
    f.kind = FaultKind::kGarbageReply;
  } else if (kind == "drop-mid-reply") {
    f.kind = FaultKind::kDropMidReply;
  } else {
    throw bad("unknown kind '" + kind + "'");
  }
  auto number = [&](const std::string& key, const std::string& value) -> int64_t {
    size_t used = 0;
    int64_t v = -1;
    try {
      v = std::stoll(value, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != value.size() || value.empty() || v < 0)
      throw bad(key + "=" + value + ": not a non-negative integer");
    return v;
  };
  bool has_ms = false;
  for (size_t i = 1; i < parts.size(); ++i) {
    const size_t eq = parts[i].find('=');
    if (eq == std::string::npos) throw bad("'" + parts[i] + "' is not KEY=VALUE");
    const std::string key = parts[i].substr(0, eq), value = parts[i].substr(eq + 1);
    if (key == "after") {
      f.skip = static_cast<int>(std::min<int64_t>(number(key, value), 1 << 30));
    } else if (key == "match") {
      f.match = value;
    } else if (key == "ms") {
      f.delay_ms = number(key, value);
      has_ms = true;
    } else {
      throw bad("unknown key '" + key + "'");
    }
  }
  if (has_ms && f.kind != FaultKind::kDelayReply) throw bad("ms= applies to delay only");
  if (f.kind == FaultKind::kDelayReply && !has_ms) throw bad("delay needs ms=MS");
  return f;
}

SecondConnection ParseSecondConnection(const std::string& text) {
  if (text == "serve") return SecondConnection::kServe;
  if (text == "queue") return SecondConnection::kQueue;
  if (text == "close") return SecondConnection::kClose;
  throw std::invalid_argument("'" + text +
                              "': a second connection is served with serve, queue "
                              "or close");
}

MockGeneratorServer::MockGeneratorServer(Mock33520B& unit, int port, ServerLimits limits)
    : impl_(std::make_unique<Impl>(unit, port, limits)) {}

MockGeneratorServer::~MockGeneratorServer() { Stop(); }

void MockGeneratorServer::Start() {
  Impl& s = *impl_;
  if (s.running) return;
  boost::system::error_code ec;
  const tcp::endpoint ep(asio::ip::make_address("127.0.0.1"),
                         static_cast<unsigned short>(s.requested_port));
  s.acceptor.open(ep.protocol(), ec);
  if (!ec) s.acceptor.set_option(tcp::acceptor::reuse_address(true), ec);
  if (!ec) s.acceptor.bind(ep, ec);
  if (!ec) s.acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) {
    boost::system::error_code ignored;
    s.acceptor.close(ignored);
    throw std::runtime_error("mock generator: cannot listen on 127.0.0.1:" +
                             std::to_string(s.requested_port) + " (" + ec.message() + ")");
  }
  s.bound_port = s.acceptor.local_endpoint().port();
  s.Accept();
  s.running = true;
  s.thread = std::thread([&s] { s.io.run(); });
}

void MockGeneratorServer::Stop() {
  Impl& s = *impl_;
  if (!s.running) return;
  asio::post(s.io, [&s] {
    boost::system::error_code ignored;
    s.acceptor.close(ignored);
    auto waiting = std::move(s.waiting);  // not served again by OnClosed below
    for (auto& w : s.sessions) {
      if (auto p = w.lock()) p->Close();
    }
    s.io.stop();
  });
  s.thread.join();
  s.running = false;
}

int MockGeneratorServer::port() const { return impl_->bound_port; }

void MockGeneratorServer::InjectFault(Fault fault) {
  std::lock_guard lock(impl_->mu);
  impl_->faults.push_back(std::move(fault));
}

void MockGeneratorServer::ReleaseDelayedReplies() {
  Impl& s = *impl_;
  std::vector<std::pair<std::weak_ptr<Impl::Session>, std::string>> held;
  {
    std::lock_guard lock(s.mu);
    held.swap(s.held);
  }
  if (!s.running) return;
  asio::post(s.io, [held = std::move(held)]() mutable {
    for (auto& [w, bytes] : held) {
      if (auto p = w.lock()) p->Send(std::move(bytes), false);
    }
  });
}

uint64_t MockGeneratorServer::ConnectionsAccepted() const { return impl_->accepted; }

ServerStats MockGeneratorServer::Stats() const {
  std::lock_guard lock(impl_->stats_mu);
  return impl_->stats;
}

bool MockGeneratorServer::WaitForStats(const std::function<bool(const ServerStats&)>& pred,
                                       int64_t timeout_ms) const {
  std::unique_lock lock(impl_->stats_mu);
  return impl_->stats_cv.wait_for(lock, std::chrono::milliseconds(timeout_ms),
                                  [&] { return pred(impl_->stats); });
}

MockGeneratorPair::MockGeneratorPair(GeneratorPairOptions options, ClockNs clock_ns)
    : reference_wired_(options.reference_wired) {
  if (!clock_ns) {
    clock_ns = [] {
      return static_cast<int64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                      std::chrono::steady_clock::now().time_since_epoch())
                                      .count());
    };
  }
  unit1_ = std::make_unique<Mock33520B>(options.unit1, clock_ns);
  unit2_ = std::make_unique<Mock33520B>(options.unit2, clock_ns);
  unit1_->SetReferenceInput([] { return false; });  // master runs on its internal reference
  unit2_->SetReferenceInput([this] { return reference_wired_.load(); });
  if (options.trigger_wired) unit1_->AddTriggerOutTarget(unit2_.get());
  server1_ = std::make_unique<MockGeneratorServer>(*unit1_, options.port1, options.limits1);
  server2_ = std::make_unique<MockGeneratorServer>(*unit2_, options.port2, options.limits2);
  server1_->Start();
  server2_->Start();
}

MockGeneratorPair::~MockGeneratorPair() {
  server1_->Stop();
  server2_->Stop();
}

}  // namespace msmcal::sim
