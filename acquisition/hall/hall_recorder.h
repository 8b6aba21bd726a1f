#pragma once
// Hall recorder: a reader thread pulls readings and clock edges from a HallSensor and hands them,
// in batches, to a sink running on a second thread, so a slow sink (disk, session store) never
// blocks the reader. Counts are readable live from any thread.
//
// Sink failures: an exception thrown by the sink (a CSV write on a full disk) is caught on the
// sink thread, stops the recording and is reported in the result (RecorderEnd::kSinkFailed, the
// exception's message); SinkError() tells it live. A sink call that does not return within
// sink_timeout_ms once the reader has finished ends Wait() with RecorderEnd::kSinkHung: the sink
// thread is then abandoned (detached; it keeps only its own copy of the sink and the queue
// alive), so whatever the sink captured must stay valid until the process ends (hold it by
// shared_ptr in the sink); the caller is expected to go to the safe state and exit.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "drivers/hall_mcu/hall_sensor.h"

namespace msmcal::acquisition {

struct HallRecorderOptions {
  // Stop after this much MCU time of readings, counted from the first reading (summed across MCU
  // resets); readings at or beyond it are not delivered. 0: no limit.
  double max_seconds = 0;
  bool stop_on_end_of_data = true;  // the MCU (mock/replay) said its source is exhausted
  bool stop_on_stall = true;        // a stall ends the recording; else keep reading, counting them
  // Send (optional) rate and sensor settings, then StartStreaming, at Start(); StopStreaming at
  // the end. After a detected MCU reset the same commands are sent again (the MCU boots idle).
  bool control_streaming = true;
  std::optional<uint16_t> rate_hz;
  std::optional<hall_mcu::SensorSettings> settings;
  // Queue between reader and sink, in batches. When it is full the reader drops the batch and
  // counts it (it never blocks).
  size_t queue_capacity = 4096;
  // Wait() gives up on a sink call still running this long after the reader finished.
  int sink_timeout_ms = 30000;

  std::string Validate() const;  // empty when valid; else field, value, constraint
};

using HallBatchSink = std::function<void(const hall_mcu::HallBatch& batch)>;

struct HallRecorderCounts {
  hall_mcu::HallCounters driver;    // as the driver counted them (received, lost, CRC, resets...)
  uint64_t readings_delivered = 0;  // handed to the sink
  uint64_t edges_delivered = 0;
  uint64_t marg_delivered = 0;
  uint64_t batches_dropped = 0;  // queue overflow (readings in them are lost to the sink)
  uint64_t readings_dropped = 0;
  double seconds_recorded = 0;  // MCU time covered so far
};

enum class RecorderEnd {
  kRunning,
  kStopped,        // Stop() was called
  kDuration,       // max_seconds reached
  kEndOfData,      // the source said it is exhausted
  kStall,          // nothing arrived within the driver's stall deadline
  kClosed,         // the device went away
  kCommandFailed,  // a start/settings command failed
  kSinkFailed,     // the sink threw (message: what it said); the recording was stopped
  kSinkHung,       // a sink call did not return within sink_timeout_ms (thread abandoned)
};
const char* ToString(RecorderEnd end);

struct HallRecorderResult {
  RecorderEnd end = RecorderEnd::kRunning;
  std::string message;
  HallRecorderCounts counts;
};

class HallRecorder {
 public:
  // `sensor` must outlive the recorder and is used only from the reader thread while running.
  // Throws std::invalid_argument if the options are invalid.
  HallRecorder(hall_mcu::HallSensor& sensor, HallBatchSink sink, HallRecorderOptions options);
  ~HallRecorder();  // Stop() and Wait()
  HallRecorder(const HallRecorder&) = delete;
  HallRecorder& operator=(const HallRecorder&) = delete;

  void Start();
  // Asks the reader to finish; it does within the driver's stall deadline. Non-blocking.
  void Stop();
  // Joins the reader, then waits for the sink to drain the queue: every delivered batch has been
  // passed to the sink when it returns, unless the sink failed (kSinkFailed: the batches after
  // the failure count as dropped) or hung (kSinkHung, see above). Never blocks longer than the
  // driver's stall deadline plus sink_timeout_ms per pending sink call.
  HallRecorderResult Wait();
  // Waits up to `timeout` for the reader to finish (it then still drains the sink: call Wait()).
  // Returns true when the reader has finished.
  bool WaitForReader(std::chrono::milliseconds timeout);
  HallRecorderCounts Counts() const;  // live, thread-safe
  // Empty while the sink works; else what the failed sink call threw. Live, thread-safe.
  std::string SinkError() const;

 private:
  struct Shared;  // what the reader, the sink thread and the caller share
  void ReaderLoop();
  static void SinkLoop(const std::shared_ptr<Shared>& shared);
  bool SendStartCommands(std::string* why);
  void Finish(RecorderEnd end, std::string message);
  // Drops what lies beyond max_seconds; returns true when the limit is reached.
  bool TrimToDuration(hall_mcu::HallBatch* batch);

  hall_mcu::HallSensor& sensor_;
  HallRecorderOptions options_;
  std::thread reader_;
  std::thread sink_thread_;
  std::shared_ptr<Shared> shared_;
  bool finished_ = false;  // Wait() has settled the result (caller's thread only)

  // Reader-thread state for the duration limit.
  bool have_origin_ = false;
  uint32_t epoch_ = 0;
  int64_t epoch_first_us_ = 0;
  int64_t epoch_last_us_ = 0;
  int64_t elapsed_before_epoch_us_ = 0;
};

}  // namespace msmcal::acquisition
