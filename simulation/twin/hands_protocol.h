#pragma once
// The twin's "hands": the messages that change the physical state of the digital twin (what a
// person or a motorised stage does at a real rig), exchanged over a Unix domain socket
// (docs/twin.md). One request per connection: a JSON document on one line, answered by one JSON
// line once the new state is in effect.
//
//   {"msmcal_setup": 1, "kind": "setup", "camera": "C1" | "C2", "msm_mounted": false,
//    "top_frame_mounted": true,
//    "sliding_plate": {"mounted": true, "pose": 2, "distance_mm": 35.0, "tilt_deg": 12.0},
//    "beams_unblocked": [1, 2, 3], ...}
//   {"msmcal_setup": 1, "kind": "truth_request", "dir": "/abs/path/truth"}
//
// Unknown fields are ignored (block, of, for, drive, changes, text are informative); a field
// that is absent leaves that part of the state as it is; a field of the wrong type is refused
// with a message naming it. Answers: {"ok": true, "generation": N} or {"ok": false, "error":
// "..."}.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace msmcal::twin {

struct SlidingPlateSetup {
  bool mounted = false;
  int pose = 0;  // index into the twin's step 1 pose design
  std::optional<double> distance_mm;
  std::optional<double> tilt_deg;
};

// A set-up: every field optional (absent: unchanged).
struct TwinSetup {
  std::optional<int> camera;  // 1 (C1) or 2 (C2)
  std::optional<bool> msm_mounted;
  std::optional<bool> top_frame_mounted;
  std::optional<SlidingPlateSetup> sliding_plate;
  std::optional<std::vector<int>> beams_unblocked;
  std::string for_step;  // informative ("step1", "hall_background", ...), for the twin's log
  int block = 0, of = 0;
};

struct HandsRequest {
  enum class Kind { kSetup, kTruthRequest };
  Kind kind = Kind::kSetup;
  TwinSetup setup;  // kSetup
  std::string dir;  // kTruthRequest: absolute folder the truth is written into
};

// Parses one request. Throws std::invalid_argument naming the field (e.g. "sliding_plate.pose:
// expected an integer, got \"2\"") for malformed JSON, a missing or unsupported msmcal_setup or
// kind, wrong types or values out of range (camera not C1/C2, beam ids < 1, pose < 0).
HandsRequest ParseHandsRequest(const std::string& json_text);
// The request as one JSON line (no trailing newline); ParseHandsRequest(Format(r)) == r.
std::string FormatHandsRequest(const HandsRequest& request);

struct HandsReply {
  bool ok = false;
  uint64_t generation = 0;  // the twin's state generation after the change
  std::string error;
};
HandsReply ParseHandsReply(const std::string& json_text);  // throws std::invalid_argument
std::string FormatHandsReply(const HandsReply& reply);

// Client side: connects to the twin's socket, sends `request_line` (newlines in it become spaces),
// waits up to timeout_ms for the answer. Throws std::runtime_error naming the socket when the twin
// cannot be reached or does not answer in time.
HandsReply SendHandsRequest(const std::string& socket_path, const std::string& request_line,
                            int timeout_ms);

}  // namespace msmcal::twin
