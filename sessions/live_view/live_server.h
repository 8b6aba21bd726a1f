#pragma once
// The live view's HTTP server (issue 19), on cpp-httplib (Debian libcpp-httplib-dev; private to
// this library): the static page (embedded in the binary at build time, no external network)
// and its API.
//
//   GET  /                      the page (index.html; live.js, live.css beside it)
//   GET  /api/state             the LiveView's state (JSON, docs/guided.md "Live view")
//   GET  /api/events            server-sent events: one `data: <state JSON>` per change,
//                               `: keepalive` comments otherwise (at least every second);
//                               ?controller=TOKEN keeps that controller's lease while open
//   GET  /api/image.jpg         the latest annotated camera image (404 before the first)
//   POST /api/claim             ?previous=TOKEN: become the controlling page -> {"controller"}
//   POST /api/ready|repeat|abort ?controller=TOKEN&prompt=ID -> {"ok": true} or {"error"}
// Every POST must carry the header `X-Msmcal-Request: 1` (a cross-site page cannot send it
// without a CORS preflight, which this server never grants). Errors answer with a JSON
// {"error": "..."} and 400 / 403 / 404 / 409.
//
// Bound to 127.0.0.1 by default. Another address needs LiveServerOptions::allow_remote (the CLI's
// explicit --ui-bind), and then every request must carry a random access token generated at
// start: `?token=T` in the URL (printed at start; the page's requests then carry the cookie the
// server sets).

#include <memory>
#include <string>

#include "sessions/live_view/live_view.h"

namespace msmcal::live_view {

inline constexpr int kDefaultLivePort = 8765;

struct LiveServerOptions {
  std::string bind_address = "127.0.0.1";
  int port = kDefaultLivePort;   // 0: any free port (the URL says which)
  bool allow_remote = false;     // required for an address other than 127.0.0.1 / ::1
  int threads = 16;              // connections served at once (each event stream holds one)
  std::string Validate() const;  // empty when valid; names field, value and constraint
};

// `--ui web[:PORT]`: returns the port (kDefaultLivePort when not given; 0: any free port).
// Throws std::invalid_argument naming the value for anything else.
int ParseUiWebOption(const std::string& value);

bool IsLoopbackAddress(const std::string& address);

class LiveServer {
 public:
  // Binds and starts serving on its own threads. Throws std::invalid_argument for invalid
  // options, std::runtime_error when the address/port cannot be bound (in use: says so).
  static std::unique_ptr<LiveServer> Start(LiveView& view, const LiveServerOptions& options);
  ~LiveServer();  // Stop()
  LiveServer(const LiveServer&) = delete;
  LiveServer& operator=(const LiveServer&) = delete;

  // Ends the event streams (within a second), stops listening and joins the threads.
  void Stop();
  int port() const;
  // "http://127.0.0.1:8765/" (with "?token=..." when a token is required).
  std::string url() const;
  const std::string& access_token() const;  // empty on loopback

 private:
  struct Impl;
  explicit LiveServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace msmcal::live_view
