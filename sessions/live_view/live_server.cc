#include "sessions/live_view/live_server.h"

#include <httplib.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <thread>

#include "sessions/live_view/page_assets.h"

namespace msmcal::live_view {
namespace {

std::string RandomHex(int bytes) {
  std::random_device rd;
  static const char kHex[] = "0123456789abcdef";
  std::string s;
  for (int i = 0; i < bytes; ++i) {
    const unsigned v = rd() & 0xff;
    s += kHex[v >> 4];
    s += kHex[v & 15];
  }
  return s;
}

void JsonError(httplib::Response& res, int status, const std::string& error) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(nlohmann::json{{"error", error}}.dump(), "application/json");
}

// The value of cookie `name` in a Cookie header ("a=1; msmcal_token=abc").
std::string CookieValue(const std::string& header, const std::string& name) {
  size_t pos = 0;
  while (pos < header.size()) {
    while (pos < header.size() && (header[pos] == ' ' || header[pos] == ';')) ++pos;
    const size_t end = header.find(';', pos);
    const std::string item = header.substr(pos, end == std::string::npos ? end : end - pos);
    if (item.rfind(name + "=", 0) == 0) return item.substr(name.size() + 1);
    if (end == std::string::npos) break;
    pos = end + 1;
  }
  return {};
}

int64_t ParseInt(const std::string& s) {
  if (s.empty() || s.size() > 18) return -1;
  for (char c : s)
    if (!std::isdigit(static_cast<unsigned char>(c))) return -1;
  return std::stoll(s);
}

}  // namespace

bool IsLoopbackAddress(const std::string& address) {
  return address == "127.0.0.1" || address == "::1" || address == "localhost";
}

std::string LiveServerOptions::Validate() const {
  if (bind_address.empty()) return "LiveServerOptions.bind_address is empty";
  if (!IsLoopbackAddress(bind_address) && !allow_remote)
    return "LiveServerOptions.bind_address = " + bind_address +
           ": not a loopback address; binding it needs allow_remote (--ui-bind) and then "
           "requires the access token";
  if (port < 0 || port > 65535)
    return "LiveServerOptions.port = " + std::to_string(port) + ": must be in [0, 65535]";
  if (threads < 2)
    return "LiveServerOptions.threads = " + std::to_string(threads) + ": must be >= 2";
  return {};
}

int ParseUiWebOption(const std::string& value) {
  if (value == "web") return kDefaultLivePort;
  if (value.rfind("web:", 0) == 0) {
    const int64_t port = ParseInt(value.substr(4));
    if (port >= 0 && port <= 65535) return static_cast<int>(port);
  }
  throw std::invalid_argument("--ui " + value +
                              ": expected web or web:PORT (PORT in 0..65535; 0: any free port)");
}

struct LiveServer::Impl {
  LiveView* view = nullptr;
  LiveServerOptions options;
  std::string token;
  int port = 0;
  httplib::Server server;
  std::thread thread;
  std::atomic<bool> stopping{false};
  std::atomic<bool> listen_returned{false};
  bool stopped = false;

  bool Authorised(const httplib::Request& req) const {
    if (token.empty()) return true;
    if (req.has_param("token") && req.get_param_value("token") == token) return true;
    return CookieValue(req.get_header_value("Cookie"), "msmcal_token") == token;
  }

  void Routes() {
    server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
      if (!Authorised(req)) {
        JsonError(res, 403, "access token required: open the URL msmcal printed (with ?token=)");
        return httplib::Server::HandlerResponse::Handled;
      }
      if (req.method == "POST" && req.get_header_value("X-Msmcal-Request") != "1") {
        JsonError(res, 403, "POST requests need the header X-Msmcal-Request: 1");
        return httplib::Server::HandlerResponse::Handled;
      }
      if (!token.empty() && req.has_param("token"))
        res.set_header("Set-Cookie",
                       "msmcal_token=" + token + "; Path=/; HttpOnly; SameSite=Strict");
      return httplib::Server::HandlerResponse::Unhandled;
    });
    for (size_t i = 0; i < kPageAssetCount; ++i) {
      const PageAsset& a = kPageAssets[i];
      auto serve = [a](const httplib::Request&, httplib::Response& res) {
        res.set_header("Cache-Control", "no-cache");
        res.set_content(reinterpret_cast<const char*>(a.data), a.size, a.content_type);
      };
      server.Get(a.path, serve);
      if (std::string(a.path) == "/index.html") server.Get("/", serve);
    }
    server.Get("/api/state", [this](const httplib::Request&, httplib::Response& res) {
      res.set_header("Cache-Control", "no-store");
      res.set_content(view->StateJson(), "application/json");
    });
    server.Get("/api/image.jpg", [this](const httplib::Request&, httplib::Response& res) {
      uint64_t seq = 0;
      const auto image = view->Image(&seq);
      if (!image) return JsonError(res, 404, "no camera image yet");
      res.set_header("Cache-Control", "no-store");
      res.set_header("X-Image-Sequence", std::to_string(seq));
      res.set_content(*image, "image/jpeg");
    });
    server.Get("/api/events", [this](const httplib::Request& req, httplib::Response& res) {
      const std::string controller =
          req.has_param("controller") ? req.get_param_value("controller") : "";
      res.set_header("Cache-Control", "no-store");
      res.set_header("X-Accel-Buffering", "no");
      auto last = std::make_shared<uint64_t>(0);
      res.set_chunked_content_provider(
          "text/event-stream", [this, controller, last](size_t, httplib::DataSink& sink) {
            if (stopping.load()) {
              sink.done();
              return true;
            }
            view->SeeController(controller);
            std::string msg;
            if (*last == 0) {
              *last = view->version();
              msg = "retry: 1000\ndata: " + view->StateJson() + "\n\n";
            } else {
              const uint64_t v = view->WaitForChange(*last, view->keepalive_interval());
              if (stopping.load()) {
                sink.done();
                return true;
              }
              if (v != *last) {
                *last = v;
                msg = "data: " + view->StateJson() + "\n\n";
              } else {
                msg = ": keepalive\n\n";
              }
            }
            return sink.write(msg.data(), msg.size());
          });
    });
    server.Post("/api/claim", [this](const httplib::Request& req, httplib::Response& res) {
      const Reply r = view->Claim(req.has_param("previous") ? req.get_param_value("previous") : "");
      if (r.http_status != 200) return JsonError(res, r.http_status, r.error);
      res.set_header("Cache-Control", "no-store");
      res.set_content(nlohmann::json{{"controller", r.controller_token}}.dump(),
                      "application/json");
    });
    for (Command c : {Command::kReady, Command::kRepeat, Command::kAbort}) {
      server.Post(std::string("/api/") + ToString(c), [this, c](const httplib::Request& req,
                                                                httplib::Response& res) {
        const std::string controller =
            req.has_param("controller") ? req.get_param_value("controller") : "";
        int64_t prompt = -1;
        if (c != Command::kAbort) {
          prompt = req.has_param("prompt") ? ParseInt(req.get_param_value("prompt")) : -1;
          if (prompt < 0)
            return JsonError(res, 400, "prompt=ID is required (the instruction answered)");
        }
        const Reply r = view->Submit(controller, c, prompt);
        if (r.http_status != 200) return JsonError(res, r.http_status, r.error);
        res.set_header("Cache-Control", "no-store");
        res.set_content(R"({"ok":true})", "application/json");
      });
    }
    server.set_error_handler([](const httplib::Request&, httplib::Response& res) {
      if (res.body.empty()) {
        res.set_header("Cache-Control", "no-store");
        res.set_content(nlohmann::json{{"error", "HTTP " + std::to_string(res.status)}}.dump(),
                        "application/json");
      }
    });
  }
};

std::unique_ptr<LiveServer> LiveServer::Start(LiveView& view, const LiveServerOptions& options) {
  if (std::string e = options.Validate(); !e.empty()) throw std::invalid_argument(e);
  auto impl = std::make_unique<Impl>();
  impl->view = &view;
  impl->options = options;
  if (!IsLoopbackAddress(options.bind_address)) impl->token = RandomHex(16);
  const int threads = options.threads;
  impl->server.new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  // SO_REUSEADDR only (httplib's default adds SO_REUSEPORT, which would let a second msmcal
  // share the port silently).
  impl->server.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  impl->server.set_keep_alive_timeout(2);
  impl->Routes();
  const std::string host = options.bind_address == "localhost" ? "127.0.0.1" : options.bind_address;
  if (options.port == 0) {
    impl->port = impl->server.bind_to_any_port(host);
    if (impl->port <= 0)
      throw std::runtime_error("live view: cannot bind " + host + " to any port");
  } else {
    if (!impl->server.bind_to_port(host, options.port))
      throw std::runtime_error("live view: cannot bind " + host + ":" +
                               std::to_string(options.port) +
                               " (in use by another program? choose another with --ui web:PORT, "
                               "or web:0 for any free port)");
    impl->port = options.port;
  }
  Impl* raw = impl.get();
  impl->thread = std::thread([raw] {
    raw->server.listen_after_bind();
    raw->listen_returned.store(true);
  });
  return std::unique_ptr<LiveServer>(new LiveServer(std::move(impl)));
}

LiveServer::LiveServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

LiveServer::~LiveServer() { Stop(); }

void LiveServer::Stop() {
  if (!impl_ || impl_->stopped) return;
  impl_->stopped = true;
  impl_->stopping.store(true);
  // httplib's stop() only acts on a running server: wait for the listener thread to get there
  // (it sets is_running first thing) or to have returned.
  while (!impl_->server.is_running() && !impl_->listen_returned.load()) std::this_thread::yield();
  impl_->server.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

int LiveServer::port() const { return impl_->port; }

std::string LiveServer::url() const {
  std::string host = impl_->options.bind_address;
  if (host == "0.0.0.0" || host == "::") {
    char name[256] = {};
    if (gethostname(name, sizeof(name) - 1) == 0 && name[0]) host = name;
  }
  if (host.find(':') != std::string::npos) host = "[" + host + "]";
  std::string u = "http://" + host + ":" + std::to_string(impl_->port) + "/";
  if (!impl_->token.empty()) u += "?token=" + impl_->token;
  return u;
}

const std::string& LiveServer::access_token() const { return impl_->token; }

}  // namespace msmcal::live_view
