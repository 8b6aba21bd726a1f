#include "drivers/scpi/scpi_client.h"

// clang-format off
// Boost 1.74's Asio uses std::exchange without including <utility> under C++20.
#include <utility>
// clang-format on

#include <spdlog/spdlog.h>

#include <boost/asio.hpp>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <sstream>
#include <thread>

#include "drivers/scpi/scpi_text.h"

namespace msmcal::scpi {

namespace asio = boost::asio;
using asio::ip::tcp;
using SteadyTime = std::chrono::steady_clock::time_point;

const char* ErrorKindName(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::kConnectFailed:
      return "connect failed";
    case ErrorKind::kTimeout:
      return "timeout";
    case ErrorKind::kConnectionLost:
      return "connection lost";
    case ErrorKind::kGarbage:
      return "garbage reply";
    case ErrorKind::kInstrument:
      return "instrument error";
    case ErrorKind::kNotConnected:
      return "not connected";
  }
  return "unknown";
}

std::string ScpiClientOptions::Validate() const {
  std::ostringstream os;
  if (host.empty()) {
    os << "host = '': must not be empty";
  } else if (port < 1 || port > 65535) {
    os << "port = " << port << ": must be in [1, 65535]";
  } else if (connect_timeout_ms <= 0) {
    os << "connect_timeout_ms = " << connect_timeout_ms << ": must be > 0";
  } else if (io_timeout_ms <= 0) {
    os << "io_timeout_ms = " << io_timeout_ms << ": must be > 0";
  } else if (max_line_bytes < 64) {
    os << "max_line_bytes = " << max_line_bytes << ": must be >= 64";
  }
  return os.str();
}

struct ScpiClient::Impl {
  asio::io_context io;
  tcp::socket socket{io};
  asio::steady_timer timer{io};
  std::string rx;  // received, not yet consumed
  bool connected = false;
  std::mutex mu;
  TranscriptSink sink;
  ClockNs clock;
  std::string endpoint;

  void Log(bool to_instrument, std::string text) {
    if (text.size() > 200)
      text = text.substr(0, 200) + "...(" + std::to_string(text.size()) + " B)";
    spdlog::debug("scpi {} {} {}", endpoint, to_instrument ? "<<" : ">>", text);
    if (sink) sink(TranscriptEntry{clock(), to_instrument, std::move(text)});
  }

  void Drop() {
    boost::system::error_code ignored;
    socket.shutdown(tcp::socket::shutdown_both, ignored);
    socket.close(ignored);
    connected = false;
    rx.clear();
  }

  // Runs the pending operation to completion or until `deadline`; on expiry cancels it, drops the
  // connection (the stream is out of step with its replies) and throws kTimeout.
  void Await(SteadyTime deadline, const std::string& what) {
    bool expired = false;
    timer.expires_at(deadline);
    timer.async_wait([this, &expired](const boost::system::error_code& ec) {
      if (!ec) {
        expired = true;
        boost::system::error_code ignored;
        socket.cancel(ignored);
      }
    });
    io.restart();
    io.run();
    if (expired) {
      Drop();
      throw ScpiError(ErrorKind::kTimeout, endpoint + ": deadline expired " + what);
    }
  }

  void Fail(const boost::system::error_code& ec, const std::string& what) {
    Drop();
    throw ScpiError(ErrorKind::kConnectionLost,
                    endpoint + ": connection lost " + what + " (" + ec.message() + ")");
  }

  void RequireConnected(const std::string& what) {
    if (!connected) {
      throw ScpiError(ErrorKind::kNotConnected, endpoint + ": not connected " + what);
    }
  }

  void SendRaw(const std::string& bytes, SteadyTime deadline, const std::string& what) {
    RequireConnected(what);
    boost::system::error_code result;
    asio::async_write(socket, asio::buffer(bytes),
                      [this, &result](const boost::system::error_code& ec, size_t) {
                        result = ec;
                        timer.cancel();
                      });
    Await(deadline, what);
    if (result) Fail(result, what);
  }

  // Reads more bytes into rx.
  void ReadSome(SteadyTime deadline, const std::string& what) {
    RequireConnected(what);
    char buf[65536];
    boost::system::error_code result;
    size_t got = 0;
    socket.async_read_some(asio::buffer(buf),
                           [this, &result, &got](const boost::system::error_code& ec, size_t n) {
                             result = ec;
                             got = n;
                             timer.cancel();
                           });
    Await(deadline, what);
    if (result) Fail(result, what);
    rx.append(buf, got);
  }

  std::string ReadLine(SteadyTime deadline, size_t max_bytes, const std::string& what) {
    for (;;) {
      const size_t nl = rx.find('\n');
      if (nl != std::string::npos) {
        std::string line = rx.substr(0, nl);
        rx.erase(0, nl + 1);
        if (!line.empty() && line.back() == '\r') line.pop_back();
        return line;
      }
      if (rx.size() > max_bytes) {
        Drop();
        throw ScpiError(ErrorKind::kGarbage, endpoint + ": reply longer than " +
                                                 std::to_string(max_bytes) + " B " + what);
      }
      ReadSome(deadline, what);
    }
  }
};

namespace detail {

std::optional<std::vector<std::string>> CallWithin(std::function<std::vector<std::string>()> lookup,
                                                   int timeout_ms) {
  struct State {
    std::mutex mu;
    std::condition_variable cv;
    bool done = false;
    std::vector<std::string> result;
    std::exception_ptr error;
  };
  auto state = std::make_shared<State>();
  std::thread([state, lookup = std::move(lookup)] {
    std::vector<std::string> r;
    std::exception_ptr e;
    try {
      r = lookup();
    } catch (...) {
      e = std::current_exception();
    }
    std::lock_guard lock(state->mu);
    state->result = std::move(r);
    state->error = e;
    state->done = true;
    state->cv.notify_all();
  }).detach();
  std::unique_lock lock(state->mu);
  if (!state->cv.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] { return state->done; }))
    return std::nullopt;
  if (state->error) std::rethrow_exception(state->error);
  return std::move(state->result);
}

}  // namespace detail

namespace {

// The addresses of `host` (a numeric address needs no lookup), resolved before `deadline`.
// Throws kConnectFailed naming the endpoint when the lookup fails or takes too long.
std::vector<tcp::endpoint> ResolveBefore(const std::string& host, int port, SteadyTime deadline,
                                         const std::string& endpoint) {
  boost::system::error_code ec;
  const asio::ip::address numeric = asio::ip::make_address(host, ec);
  if (!ec) return {tcp::endpoint(numeric, static_cast<uint16_t>(port))};
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
      deadline - std::chrono::steady_clock::now());
  std::optional<std::vector<std::string>> addresses;
  try {
    addresses = detail::CallWithin(
        [host, port] {
          asio::io_context io;
          tcp::resolver resolver(io);
          boost::system::error_code e;
          const auto results = resolver.resolve(host, std::to_string(port), e);
          if (e) throw std::runtime_error(e.message());
          std::vector<std::string> out;
          for (const auto& r : results) out.push_back(r.endpoint().address().to_string());
          return out;
        },
        static_cast<int>(std::max<int64_t>(0, left.count())));
  } catch (const std::exception& e) {
    throw ScpiError(ErrorKind::kConnectFailed,
                    endpoint + ": cannot resolve host (" + std::string(e.what()) + ")");
  }
  if (!addresses) {
    throw ScpiError(ErrorKind::kConnectFailed,
                    endpoint + ": cannot resolve host within the connect timeout");
  }
  std::vector<tcp::endpoint> out;
  for (const auto& a : *addresses)
    out.emplace_back(asio::ip::make_address(a), static_cast<uint16_t>(port));
  if (out.empty())
    throw ScpiError(ErrorKind::kConnectFailed, endpoint + ": cannot resolve host (no address)");
  return out;
}

}  // namespace

ScpiClient::ScpiClient(ScpiClientOptions options, ClockNs clock_ns)
    : options_(std::move(options)), impl_(std::make_unique<Impl>()) {
  if (const std::string err = options_.Validate(); !err.empty()) {
    throw std::invalid_argument("ScpiClientOptions: " + err);
  }
  impl_->clock = clock_ns ? std::move(clock_ns) : [] {
    return static_cast<int64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                    std::chrono::steady_clock::now().time_since_epoch())
                                    .count());
  };
  impl_->endpoint = options_.host + ":" + std::to_string(options_.port);
}

ScpiClient::~ScpiClient() { Close(); }

std::string ScpiClient::Endpoint() const { return impl_->endpoint; }

void ScpiClient::Connect() {
  std::lock_guard lock(impl_->mu);
  Impl& s = *impl_;
  s.Drop();
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(options_.connect_timeout_ms);
  boost::system::error_code ec;
  // Name resolution counts against the connect timeout.
  const std::vector<tcp::endpoint> endpoints =
      ResolveBefore(options_.host, options_.port, deadline, s.endpoint);
  boost::system::error_code result;
  asio::async_connect(s.socket, endpoints,
                      [&s, &result](const boost::system::error_code& e, const tcp::endpoint&) {
                        result = e;
                        s.timer.cancel();
                      });
  try {
    s.Await(deadline, "while connecting");
  } catch (const ScpiError& e) {
    throw ScpiError(ErrorKind::kConnectFailed, e.what());
  }
  if (result) {
    s.Drop();
    throw ScpiError(ErrorKind::kConnectFailed,
                    s.endpoint + ": cannot connect (" + result.message() + ")");
  }
  s.socket.set_option(tcp::no_delay(true), ec);
  s.connected = true;
  spdlog::debug("scpi {} connected", s.endpoint);
}

void ScpiClient::Close() {
  std::lock_guard lock(impl_->mu);
  impl_->Drop();
}

bool ScpiClient::IsConnected() const {
  std::lock_guard lock(impl_->mu);
  return impl_->connected;
}

void ScpiClient::Reconnect() {
  Close();
  Connect();
}

namespace {
SteadyTime IoDeadline(const ScpiClientOptions& o) {
  return std::chrono::steady_clock::now() + std::chrono::milliseconds(o.io_timeout_ms);
}
}  // namespace

void ScpiClient::Write(const std::string& command) {
  std::lock_guard lock(impl_->mu);
  impl_->Log(true, command);
  impl_->SendRaw(command + "\n", IoDeadline(options_), "writing '" + command + "'");
}

std::string ScpiClient::Query(const std::string& command) {
  std::lock_guard lock(impl_->mu);
  Impl& s = *impl_;
  const auto deadline = IoDeadline(options_);
  s.Log(true, command);
  s.SendRaw(command + "\n", deadline, "writing '" + command + "'");
  std::string line =
      s.ReadLine(deadline, options_.max_line_bytes, "waiting for the reply to '" + command + "'");
  if (!IsPrintable(line)) {
    s.Drop();
    throw ScpiError(ErrorKind::kGarbage,
                    s.endpoint + ": non-printable bytes in the reply to '" + command + "'");
  }
  s.Log(false, line);
  return line;
}

void ScpiClient::WriteBlock(const std::string& prefix, const std::string& payload) {
  std::lock_guard lock(impl_->mu);
  Impl& s = *impl_;
  const std::string block = FormatDefiniteBlock(payload);
  const size_t header = block.size() - payload.size();
  s.Log(true, prefix + block.substr(0, header) + "<" + std::to_string(payload.size()) + " B>");
  // Large arbs take a while on the wire: scale the deadline with the size (>= 1 MB/s).
  const auto deadline = IoDeadline(options_) + std::chrono::milliseconds(payload.size() / 1000);
  s.SendRaw(prefix + block + "\n", deadline, "writing block '" + prefix + "'");
}

std::string ScpiClient::QueryBlock(const std::string& command) {
  std::lock_guard lock(impl_->mu);
  Impl& s = *impl_;
  const std::string what = "waiting for the block reply to '" + command + "'";
  s.Log(true, command);
  auto deadline = IoDeadline(options_);
  s.SendRaw(command + "\n", deadline, "writing '" + command + "'");
  std::optional<BlockHeader> header;
  for (;;) {
    try {
      header = ParseBlockHeader(s.rx);
    } catch (const std::invalid_argument& e) {
      s.Drop();
      throw ScpiError(ErrorKind::kGarbage, s.endpoint + ": " + e.what() + " " + what);
    }
    if (header && s.rx.size() >= header->header_size + header->payload_size) break;
    if (header) {
      deadline = std::max(
          deadline, IoDeadline(options_) + std::chrono::milliseconds(header->payload_size / 1000));
    }
    s.ReadSome(deadline, what);
  }
  std::string payload = s.rx.substr(header->header_size, header->payload_size);
  s.rx.erase(0, header->header_size + header->payload_size);
  // The response message terminator follows the block.
  const std::string rest = s.ReadLine(deadline, options_.max_line_bytes, what);
  if (!Trim(rest).empty()) {
    s.Drop();
    throw ScpiError(ErrorKind::kGarbage, s.endpoint + ": bytes after the block " + what);
  }
  s.Log(false, "#<" + std::to_string(payload.size()) + " B>");
  return payload;
}

void ScpiClient::CheckErrors(const std::string& context) {
  std::vector<ErrorEntry> errors;
  // The queue holds at most 20 entries (+ overflow); a longer drain means garbage.
  for (int i = 0; i < 32; ++i) {
    const std::string reply = Query("SYST:ERR?");
    ErrorEntry e;
    try {
      e = ParseErrorEntry(reply);
    } catch (const std::invalid_argument& ex) {
      throw ScpiError(ErrorKind::kGarbage,
                      Endpoint() + ": bad SYST:ERR? reply after '" + context + "': " + ex.what());
    }
    if (e.code == 0) {
      if (errors.empty()) return;
      std::ostringstream os;
      os << Endpoint() << ": instrument reported";
      for (const ErrorEntry& x : errors) os << " [" << x.code << ", \"" << x.message << "\"]";
      os << " after '" << context << "'";
      throw ScpiError(ErrorKind::kInstrument, os.str());
    }
    errors.push_back(e);
  }
  throw ScpiError(ErrorKind::kGarbage,
                  Endpoint() + ": SYST:ERR? never reported +0 after '" + context + "'");
}

void ScpiClient::WaitOperationComplete() {
  const std::string r = Query("*OPC?");
  if (Trim(r) != "1" && Trim(r) != "+1") {
    throw ScpiError(ErrorKind::kGarbage, Endpoint() + ": *OPC? replied '" + r + "'");
  }
}

void ScpiClient::SetTranscriptSink(TranscriptSink sink) {
  std::lock_guard lock(impl_->mu);
  impl_->sink = std::move(sink);
}

}  // namespace msmcal::scpi
