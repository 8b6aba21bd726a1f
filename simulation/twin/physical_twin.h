#pragma once
// The digital twin behind the real wires (issue 20): one simulated world served as the rig's
// instruments — both Keysight 33520B units on their SCPI ports (mocks/generator), the GigE Vision
// camera on its address (mocks/camera), the Hall MCU on a pseudo-terminal (mocks/mcu) — whose
// outputs follow PHYSICALLY from what arrives over the wires and from the world's state:
//
// - the mirror moves with the drives actually applied on unit 1 (frequency, amplitude, phase,
//   output and run state per channel) through the simulator's resonator model (mocks/rig);
//   drives off: the neutral pose;
// - the laser fires at the pulses of the arbitrary waveform playing on unit 2 ch1 (decoded from
//   the uploaded samples: rising edges, repeating every arb period from the channel's start);
//   output off or not started: no light;
// - a camera frame integrates the exposure window that ends when the frame is filled: one dot
//   per pulse fired in it and per unblocked beam, landing where the beam goes (sliding plate,
//   mirror, world board: RigSimulator::StateScene), rendered by the simulator's renderer;
// - the Hall MCU streams readings at its rate in (simulated) MCU time, the field being the
//   coils' (the drives applied) + earth + the magnet at the mirror's pose (top frame mounted) or
//   the background shift (top frame removed); it timestamps the clock's rising edges (unit 2
//   ch2) only while that output is on.
//
// The physical state (camera position, MSM and top frame mounted, sliding plate, beams) changes
// only through Apply() — the hands socket's handler. One clock (injected) is the generators'
// time base, the camera's exposure clock and the MCU's time source.
//
// Thread safety: Apply/Handle/WriteTruth and the accessors may be called from any thread; the
// camera, the MCU and the generators' servers run on their own threads.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mocks/rig/rig_simulator.h"
#include "mocks/rig/sim_options.h"
#include "simulation/twin/hands_protocol.h"

namespace msmcal::twin {

struct PhysicalTwinOptions {
  sim::SimOptions sim;  // the world (config/sim.yaml defaults, overridden by the rig file)
  int port1 = 0;        // unit 1 SCPI port on 127.0.0.1; 0: any free port
  int port2 = 0;
  std::string camera_address = "127.0.0.1";  // "" : no camera (one GigE server per address)
  double camera_frame_rate_hz = 10.0;
  // Integration window of each frame (s), ending when the frame is filled. At least one pattern
  // period so that a frame shows every pulse of the trigger pattern.
  // The exposure integrated when the camera's client has not set one (GenICam ExposureTime);
  // once set, a frame integrates the camera's own exposure.
  double exposure_s = 0.5;
  std::string hall_link_path;  // symlink to the MCU's pty ("" : none; see hall_device())
  uint16_t hall_rate_hz = 1000;
  std::string hands_socket;           // Unix socket path served for the hands ("" : none)
  std::function<int64_t()> clock_ns;  // nanoseconds, monotonic; default: steady_clock
  std::string Validate() const;       // empty when valid; names field, value, constraint
};

// The twin's physical state (what Apply changes).
struct TwinState {
  int camera = 1;
  bool msm_mounted = false;
  bool top_frame_mounted = true;
  std::optional<SlidingPlateSetup> sliding_plate;  // mounted: its pose
  std::vector<int> beams_unblocked;                // default: every beam
};

// What the generators play, as the physics reads it.
struct AppliedDrive {
  bool fast_on = false, slow_on = false;  // sine running with output on
  sim::MirrorOptions mirror;              // drives in generator time (phase at t = 0)
  int64_t t0_ns = 0;                      // generator time 0 on the twin clock
  sim::DriveMode mode = sim::DriveMode::kOff;
};

// When a camera frame was filled, on the twin's clock, and the state generation it shows.
struct FrameStamp {
  int64_t exposure_start_ns = 0;
  int64_t exposure_end_ns = 0;
  uint64_t generation = 0;
};

class PhysicalTwin {
 public:
  // Starts every instrument and the hands server. Throws std::invalid_argument (Validate) or
  // std::runtime_error naming the instrument that cannot be served.
  explicit PhysicalTwin(const PhysicalTwinOptions& options);
  ~PhysicalTwin();  // stops everything, removes the socket and the symlink
  PhysicalTwin(const PhysicalTwin&) = delete;
  PhysicalTwin& operator=(const PhysicalTwin&) = delete;

  const sim::RigSimulator& sim() const;
  int generator_port(int unit) const;
  const std::string& hall_device() const;  // the pty slave

  // Applies a set-up; returns the new generation. Frames filled after the return show it.
  // Throws std::invalid_argument for a set-up the world cannot take (beam id > beam count).
  uint64_t Apply(const TwinSetup& setup);
  TwinState State() const;
  uint64_t generation() const;

  // One hands request line -> one reply (setup: Apply; truth_request: WriteTruth).
  HandsReply Handle(const std::string& request_line);

  // Writes the ground truth for the drive and trigger table last applied (the last time the
  // drives and the laser were all running) into `dir` (the files of `msmcal simulate`'s truth/,
  // directly in `dir`). Throws std::runtime_error when nothing was applied yet.
  void WriteTruth(const std::filesystem::path& dir);

  // Physics, as the instruments see it now (also for tests).
  AppliedDrive Drive() const;
  // The laser pulses of the arb in play, as generator times within one arb period, ascending;
  // empty when the laser output is off or not running.
  std::vector<double> LaserPatternTimesS() const;
  // The pulses fired in [from_ns, to_ns] of the twin clock, with the mirror's pose at each.
  std::vector<sim::PulseAtPose> PulsesBetween(int64_t from_ns, int64_t to_ns) const;
  // What a frame whose exposure ends at `end_ns` shows (state as of now).
  sim::Scene SceneAt(int64_t end_ns) const;
  int64_t NowNs() const;
  // The stamp of a recent frame (the last 256) by its GigE Vision device timestamp (what
  // camera::FrameInfo::device_timestamp_ns carries), for in-process sessions and tests that
  // discard frames exposed before a change.
  std::optional<FrameStamp> FrameStampFor(int64_t device_timestamp_ns) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace msmcal::twin
