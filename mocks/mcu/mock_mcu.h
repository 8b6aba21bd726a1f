#pragma once
// A mock Hall MCU on a pseudo-terminal: the firmware side of docs/protocols/hall-mcu.md. It
// opens a pty pair, answers commands, streams events from a McuDataSource (quantised with the
// current MLX90393 gain/resolution exactly as the host will convert them), paces them at `speed`
// times real time (0: as fast as the reader takes them), and injects faults on request while
// logging exactly what it injected.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "drivers/hall_mcu/decoder.h"
#include "drivers/hall_mcu/hall_sensor.h"
#include "drivers/hall_mcu/protocol.h"
#include "mocks/mcu/mcu_source.h"

namespace msmcal::sim {

enum class McuFaultKind {
  kFlipBit,   // one random bit of the frame is inverted (the frame is lost, CRC catches it)
  kDropByte,  // one random byte of the frame is not sent (the frame is lost)
  kReset,     // the frame is cut after a random number of bytes, then the MCU reboots
  kStall,     // before the frame, the MCU goes silent (no data, no replies) for stall_ms
};

// A fault applied to the `data_frame`-th data frame (field, clock edge or MARG; 0-based, counted
// over the whole run across resets).
struct McuFault {
  McuFaultKind kind = McuFaultKind::kFlipBit;
  uint64_t data_frame = 0;
  int64_t stall_ms = -1;  // kStall only: < 0 means until Stop()
};

// The command-line form (`msmcal mock mcu --fault`, `msmcal demo --mock-fault`): "flip@1200",
// "drop@300", "reset@5000", "stall@9000" (until stopped) or "stall@9000:2000" (ms). Throws
// std::runtime_error naming the text.
McuFault ParseMcuFault(const std::string& text);

struct MockMcuOptions {
  std::string link_path;    // if set, a symlink to the pty slave is created here (and removed)
  double speed = 0;         // 1: real time, 2: twice as fast, 0: as fast as possible
  uint16_t rate_hz = 1000;  // reported in status; the source decides the actual sample times
  int64_t heartbeat_period_us = 100000;  // status frame every this much MCU time; 0: none
  bool stream_on_open = false;  // start streaming without a command (before any boot/reset)
  bool record_sent = true;      // keep every intact reading/edge sent, for tests
  hall_mcu::IdentifyInfo identify{1, 0, 0, hall_mcu::SensorType::kMlx90393, "msmcal mock MCU"};
  hall_mcu::SensorSettings settings;  // power-up sensor settings
  std::vector<McuFault> faults;
  uint64_t seed = 7;                // fault positions within frames
  std::function<int64_t()> now_ns;  // pacing clock; default: steady_clock

  std::string Validate() const;
};

// What the mock did; compare with what the host counted.
struct MockMcuLog {
  std::vector<hall_mcu::HallSample> sent_readings;  // intact ones, values as the host converts
  std::vector<hall_mcu::ClockEdge> sent_edges;      // intact ones
  uint64_t sent_marg = 0;                           // intact ones
  uint64_t readings_sent_total = 0;                 // including damaged
  std::vector<uint32_t> damaged_reading_seqs;       // flipped/dropped (lost for the host)
  std::vector<uint32_t> damaged_edge_seqs;
  std::vector<uint32_t> damaged_marg_seqs;
  std::vector<uint32_t> truncated_reading_seqs;  // cut by a reset
  std::vector<uint32_t> truncated_edge_seqs;
  uint64_t flipped_bits = 0, dropped_bytes = 0, resets = 0, stalls = 0;
  uint64_t commands = 0;
  bool source_exhausted = false;
};

class MockMcu {
 public:
  // Opens the pty (and the symlink). Throws std::runtime_error naming what failed.
  MockMcu(const MockMcuOptions& options, std::unique_ptr<McuDataSource> source);
  ~MockMcu();  // Stop()s, closes the pty, removes the symlink
  MockMcu(const MockMcu&) = delete;
  MockMcu& operator=(const MockMcu&) = delete;

  // The slave device path (e.g. /dev/pts/5): what the driver opens.
  const std::string& device_path() const { return slave_path_; }

  void Start();  // runs the firmware loop on its own thread
  void Stop();   // wakes and joins it; idempotent

  // Blocks until the source is exhausted and its end-of-data status was written, or Stop().
  // Returns true if the source was exhausted.
  bool WaitUntilExhausted();

  MockMcuLog Log() const;  // a consistent copy

 private:
  void Loop();
  void Boot();
  void HandleCommands();
  bool WriteBytes(const std::vector<uint8_t>& bytes);  // false when stopped
  bool Flush();
  void EmitData(const McuEvent& event);
  void EmitStatus(uint8_t extra_flags);
  bool WaitFor(int64_t wait_ms);  // poll master/stop pipe; false when stopped
  int64_t NowNs() const;

  MockMcuOptions options_;
  std::unique_ptr<McuDataSource> source_;
  int master_fd_ = -1;
  int slave_fd_ = -1;
  int stop_pipe_[2] = {-1, -1};
  std::string slave_path_;
  std::thread thread_;
  std::atomic<bool> stop_{false};

  // Firmware state (loop thread only).
  bool streaming_ = false;
  hall_mcu::SensorSettings settings_;
  uint16_t rate_hz_ = 1000;
  uint32_t reading_seq_ = 0, edge_seq_ = 0, marg_seq_ = 0, status_seq_ = 0;
  int64_t boot_time_us_ = 0;  // source time of the last boot
  int64_t last_event_time_us_ = 0;
  int64_t next_heartbeat_us_ = 0;
  uint64_t data_frames_ = 0;
  size_t next_fault_ = 0;
  std::vector<McuFault> faults_;  // sorted by data_frame
  std::vector<uint8_t> out_;   // pending bytes (batched in fast mode)
  hall_mcu::FrameDecoder commands_;
  std::mt19937_64 rng_;

  mutable std::mutex mu_;
  std::condition_variable exhausted_cv_;
  MockMcuLog log_;
};

}  // namespace msmcal::sim
