#include "simulation/twin/hands_protocol.h"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace msmcal::twin {
namespace {

using nlohmann::json;

[[noreturn]] void Bad(const std::string& field, const std::string& what, const json& value) {
  throw std::invalid_argument(field + ": " + what + ", got " + value.dump());
}

bool GetBool(const json& j, const std::string& field) {
  if (!j.is_boolean()) Bad(field, "expected true or false", j);
  return j.get<bool>();
}

int GetInt(const json& j, const std::string& field) {
  if (!j.is_number_integer() && !j.is_number_unsigned()) Bad(field, "expected an integer", j);
  const int64_t v = j.get<int64_t>();
  if (v < -1000000 || v > 1000000) Bad(field, "integer out of range", j);
  return static_cast<int>(v);
}

double GetNumber(const json& j, const std::string& field) {
  if (!j.is_number()) Bad(field, "expected a number", j);
  const double v = j.get<double>();
  if (!std::isfinite(v)) Bad(field, "expected a finite number", j);
  return v;
}

std::string GetString(const json& j, const std::string& field) {
  if (!j.is_string()) Bad(field, "expected a string", j);
  return j.get<std::string>();
}

}  // namespace

HandsRequest ParseHandsRequest(const std::string& json_text) {
  const json doc = json::parse(json_text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) throw std::invalid_argument("set-up: not valid JSON");
  if (!doc.is_object()) Bad("set-up", "expected a JSON object", doc);
  if (!doc.contains("msmcal_setup")) throw std::invalid_argument("msmcal_setup: missing");
  if (GetInt(doc["msmcal_setup"], "msmcal_setup") != 1)
    Bad("msmcal_setup", "unsupported version (this twin reads 1)", doc["msmcal_setup"]);
  if (!doc.contains("kind")) throw std::invalid_argument("kind: missing");
  const std::string kind = GetString(doc["kind"], "kind");
  HandsRequest r;
  if (kind == "truth_request") {
    r.kind = HandsRequest::Kind::kTruthRequest;
    if (!doc.contains("dir")) throw std::invalid_argument("dir: missing (truth_request)");
    r.dir = GetString(doc["dir"], "dir");
    if (r.dir.empty() || r.dir[0] != '/') Bad("dir", "expected an absolute path", doc["dir"]);
    return r;
  }
  if (kind != "setup") Bad("kind", "expected \"setup\" or \"truth_request\"", doc["kind"]);
  TwinSetup& s = r.setup;
  if (doc.contains("camera")) {
    const std::string c = GetString(doc["camera"], "camera");
    if (c != "C1" && c != "C2") Bad("camera", "expected \"C1\" or \"C2\"", doc["camera"]);
    s.camera = c == "C1" ? 1 : 2;
  }
  if (doc.contains("msm_mounted")) s.msm_mounted = GetBool(doc["msm_mounted"], "msm_mounted");
  if (doc.contains("top_frame_mounted"))
    s.top_frame_mounted = GetBool(doc["top_frame_mounted"], "top_frame_mounted");
  if (doc.contains("sliding_plate")) {
    const json& p = doc["sliding_plate"];
    if (!p.is_object()) Bad("sliding_plate", "expected an object", p);
    SlidingPlateSetup plate;
    if (!p.contains("mounted")) throw std::invalid_argument("sliding_plate.mounted: missing");
    plate.mounted = GetBool(p["mounted"], "sliding_plate.mounted");
    if (plate.mounted) {
      if (!p.contains("pose"))
        throw std::invalid_argument("sliding_plate.pose: missing (plate mounted)");
      plate.pose = GetInt(p["pose"], "sliding_plate.pose");
      if (plate.pose < 0) Bad("sliding_plate.pose", "expected >= 0", p["pose"]);
      if (p.contains("distance_mm") && !p["distance_mm"].is_null())
        plate.distance_mm = GetNumber(p["distance_mm"], "sliding_plate.distance_mm");
      if (p.contains("tilt_deg") && !p["tilt_deg"].is_null())
        plate.tilt_deg = GetNumber(p["tilt_deg"], "sliding_plate.tilt_deg");
    }
    s.sliding_plate = plate;
  }
  if (doc.contains("beams_unblocked")) {
    const json& b = doc["beams_unblocked"];
    if (!b.is_array()) Bad("beams_unblocked", "expected a list of beam ids", b);
    std::vector<int> ids;
    for (size_t i = 0; i < b.size(); ++i) {
      const std::string field = "beams_unblocked[" + std::to_string(i) + "]";
      const int id = GetInt(b[i], field);
      if (id < 1) Bad(field, "expected a beam id >= 1", b[i]);
      ids.push_back(id);
    }
    s.beams_unblocked = ids;
  }
  if (doc.contains("for")) {
    const json& f = doc["for"];
    if (!f.is_object()) Bad("for", "expected an object", f);
    if (f.contains("step")) s.for_step = GetString(f["step"], "for.step");
  }
  if (doc.contains("block")) s.block = GetInt(doc["block"], "block");
  if (doc.contains("of")) s.of = GetInt(doc["of"], "of");
  return r;
}

std::string FormatHandsRequest(const HandsRequest& r) {
  json j;
  j["msmcal_setup"] = 1;
  if (r.kind == HandsRequest::Kind::kTruthRequest) {
    j["kind"] = "truth_request";
    j["dir"] = r.dir;
    return j.dump();
  }
  const TwinSetup& s = r.setup;
  j["kind"] = "setup";
  if (s.camera) j["camera"] = *s.camera == 1 ? "C1" : "C2";
  if (s.msm_mounted) j["msm_mounted"] = *s.msm_mounted;
  if (s.top_frame_mounted) j["top_frame_mounted"] = *s.top_frame_mounted;
  if (s.sliding_plate) {
    json p;
    p["mounted"] = s.sliding_plate->mounted;
    if (s.sliding_plate->mounted) {
      p["pose"] = s.sliding_plate->pose;
      if (s.sliding_plate->distance_mm) p["distance_mm"] = *s.sliding_plate->distance_mm;
      if (s.sliding_plate->tilt_deg) p["tilt_deg"] = *s.sliding_plate->tilt_deg;
    }
    j["sliding_plate"] = p;
  }
  if (s.beams_unblocked) j["beams_unblocked"] = *s.beams_unblocked;
  if (!s.for_step.empty()) j["for"] = json{{"step", s.for_step}};
  if (s.block) j["block"] = s.block;
  if (s.of) j["of"] = s.of;
  return j.dump();
}

HandsReply ParseHandsReply(const std::string& text) {
  const json doc = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object() || !doc.contains("ok") || !doc["ok"].is_boolean())
    throw std::invalid_argument("twin reply: not a hands reply: " + text);
  HandsReply r;
  r.ok = doc["ok"].get<bool>();
  if (doc.contains("generation") && doc["generation"].is_number_unsigned())
    r.generation = doc["generation"].get<uint64_t>();
  if (doc.contains("error") && doc["error"].is_string()) r.error = doc["error"].get<std::string>();
  return r;
}

std::string FormatHandsReply(const HandsReply& r) {
  json j;
  j["ok"] = r.ok;
  j["generation"] = r.generation;
  if (!r.error.empty()) j["error"] = r.error;
  return j.dump();
}

HandsReply SendHandsRequest(const std::string& socket_path, const std::string& request_line,
                            int timeout_ms) {
  const std::string who = "twin hands socket " + socket_path;
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (socket_path.size() >= sizeof(addr.sun_path))
    throw std::runtime_error(who + ": path too long for a Unix socket");
  std::memcpy(addr.sun_path, socket_path.c_str(), socket_path.size() + 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::runtime_error(who + ": socket: " + std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0)
    throw std::runtime_error(
        who + ": cannot connect (is `msmcal mock rig` running?): " + std::strerror(errno));
  // One line on the wire: a raw newline can only be JSON whitespace (JSON strings escape theirs).
  std::string line = request_line;
  for (char& c : line)
    if (c == '\n' || c == '\r') c = ' ';
  line += '\n';
  size_t sent = 0;
  while (sent < line.size()) {
    const ssize_t n = ::send(fd, line.data() + sent, line.size() - sent, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw std::runtime_error(who + ": send: " + std::strerror(errno));
    sent += static_cast<size_t>(n);
  }
  std::string reply;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (reply.find('\n') == std::string::npos) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                          deadline - std::chrono::steady_clock::now())
                          .count();
    if (left <= 0)
      throw std::runtime_error(who + ": no answer within " + std::to_string(timeout_ms) + " ms");
    pollfd p{fd, POLLIN, 0};
    const int pr = ::poll(&p, 1, static_cast<int>(left));
    if (pr < 0 && errno == EINTR) continue;
    if (pr <= 0) continue;
    char buf[4096];
    const ssize_t n = ::recv(fd, buf, sizeof(buf), 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw std::runtime_error(who + ": the twin closed the connection without answering");
    reply.append(buf, static_cast<size_t>(n));
  }
  return ParseHandsReply(reply.substr(0, reply.find('\n')));
}

}  // namespace msmcal::twin
