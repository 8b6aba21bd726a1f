#pragma once
// The Hall MCU as the host sees it: value types with MCU timestamps, live counters, and the narrow
// `HallSensor` interface. The real implementation (Boost.Asio serial port, kept private) comes
// from OpenHallMcu(). The acquisition side never sees bytes.

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/status.h"
#include "drivers/hall_mcu/protocol.h"

namespace msmcal::hall_mcu {

// One MLX90393 reading. `epoch` counts MCU resets seen by this connection (0 before the first
// reset): mcu_time_us and seq restart at each reset, so (epoch, mcu_time_us) orders readings.
struct HallSample {
  uint32_t epoch = 0;
  uint32_t seq = 0;
  int64_t mcu_time_us = 0;                   // MCU time at the start of the conversion
  double bx_uT = 0, by_uT = 0, bz_uT = 0;    // sensor frame, converted per the datasheet table
  uint16_t reg_x = 0, reg_y = 0, reg_z = 0;  // raw output registers
  uint8_t gain_sel = 0, res_x = 0, res_y = 0, res_z = 0;
};

// MCU time of one rising edge of generator 2's clock output (pattern phase 0).
struct ClockEdge {
  uint32_t epoch = 0;
  uint32_t seq = 0;
  int64_t mcu_time_us = 0;
};

// One MARG-board reading (accelerometer, gyro, magnetometer) in the board's sensor frame.
struct MargReading {
  uint32_t epoch = 0;
  uint32_t seq = 0;
  int64_t mcu_time_us = 0;
  std::array<double, 3> accel_g{};
  std::array<double, 3> gyro_dps{};
  std::array<double, 3> mag_uT{};
};

// What arrived since the last read, in wire order within each vector.
struct HallBatch {
  std::vector<HallSample> readings;
  std::vector<ClockEdge> edges;
  std::vector<MargReading> marg;
  bool end_of_data = false;  // the MCU reported kStatusEndOfData (mock sources only)
  bool mcu_reset = false;    // an MCU reset was detected (it boots idle: restart streaming)
  bool empty() const { return readings.empty() && edges.empty() && marg.empty(); }
  void clear() {
    readings.clear();
    edges.clear();
    marg.clear();
    end_of_data = false;
    mcu_reset = false;
  }
};

// Cumulative counts since the connection opened. Losses are exact for frames lost between two
// frames of the same type that did arrive, or before a status frame that did arrive; frames lost
// in flight when the MCU resets are not knowable by the host (counted in crc_errors/bytes only).
struct HallCounters {
  uint64_t readings = 0;
  uint64_t clock_edges = 0;
  uint64_t marg_readings = 0;
  uint64_t status_frames = 0;
  uint64_t readings_lost = 0;     // sequence gaps in field readings
  uint64_t clock_edges_lost = 0;  // sequence gaps in clock edges
  uint64_t marg_lost = 0;         // sequence gaps in MARG readings
  uint64_t resets = 0;            // MCU resets detected (boot status or time going backwards)
  uint64_t crc_errors = 0;        // frames with a plausible header and a bad CRC
  uint64_t bad_headers = 0;       // sync found but unknown type or impossible length
  uint64_t bytes_discarded = 0;   // bytes skipped while resynchronising
  uint64_t stalls = 0;            // reads that hit the stall deadline
  uint64_t sensor_overruns = 0;   // as last reported by the MCU's status frame
};

struct DeviceInfo {
  IdentifyInfo identify;
  std::string ToString() const;
};

enum class ReadStatus {
  kOk,      // at least one item was appended, or end_of_data / mcu_reset was set
  kStall,   // nothing complete arrived within the stall deadline
  kClosed,  // the device went away (EOF / I/O error: unplugged)
};
const char* ToString(ReadStatus status);

struct ReadResult {
  ReadStatus status = ReadStatus::kOk;
  std::string message;  // why, for kStall and kClosed
};

// Result of a command: ok, or a message naming the command and what failed (rejected by the MCU:
// kDeviceError, no reply within the deadline: kTimeout, I/O error: kUnavailable); the drivers'
// one result type (common/status.h).
using CommandResult = common::Status;
using common::StatusCode;

struct HallMcuOptions {
  std::string device = "/dev/ttyACM0";  // serial device path (a pty path works the same)
  unsigned baud_rate = 921600;          // ignored by USB CDC and ptys, set anyway
  int stall_timeout_ms = 500;           // Read(): no complete frame within this -> kStall
  int command_timeout_ms = 1000;        // each command waits this long for its reply

  // Empty when valid; else names the field, its value and the constraint.
  std::string Validate() const;
};

// The Hall MCU. Not thread-safe: one thread owns it (the recorder's reader thread). Every call
// returns within its deadline; none blocks forever.
class HallSensor {
 public:
  virtual ~HallSensor() = default;

  virtual CommandResult Identify(DeviceInfo* info) = 0;
  virtual CommandResult StartStreaming() = 0;
  virtual CommandResult StopStreaming() = 0;
  virtual CommandResult SetRate(uint16_t rate_hz) = 0;
  virtual CommandResult SetSensor(const SensorSettings& settings) = 0;
  // Asks for a status frame; its content updates counters() (and loss accounting).
  virtual CommandResult RequestStatus() = 0;

  // Appends what arrives to *batch; returns as soon as something complete arrived (after draining
  // what is already buffered), or kStall after stall_timeout_ms of silence, or kClosed.
  virtual ReadResult Read(HallBatch* batch) = 0;

  virtual const HallCounters& counters() const = 0;
};

// Opens the serial device (raw mode, 8N1, no flow control). Throws std::runtime_error naming the
// device if it cannot be opened or the options are invalid.
std::unique_ptr<HallSensor> OpenHallMcu(const HallMcuOptions& options);

}  // namespace msmcal::hall_mcu
