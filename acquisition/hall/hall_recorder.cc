#include "acquisition/hall/hall_recorder.h"

#include <cmath>
#include <stdexcept>
#include <utility>

namespace msmcal::acquisition {

const char* ToString(RecorderEnd end) {
  switch (end) {
    case RecorderEnd::kRunning:
      return "running";
    case RecorderEnd::kStopped:
      return "stopped";
    case RecorderEnd::kDuration:
      return "duration";
    case RecorderEnd::kEndOfData:
      return "end_of_data";
    case RecorderEnd::kStall:
      return "stall";
    case RecorderEnd::kClosed:
      return "closed";
    case RecorderEnd::kCommandFailed:
      return "command_failed";
    case RecorderEnd::kSinkFailed:
      return "sink_failed";
    case RecorderEnd::kSinkHung:
      return "sink_hung";
  }
  return "unknown";
}

std::string HallRecorderOptions::Validate() const {
  if (!(max_seconds >= 0) || !std::isfinite(max_seconds)) {
    return "HallRecorderOptions.max_seconds = " + std::to_string(max_seconds) +
           ": violated constraint finite and >= 0";
  }
  if (queue_capacity == 0) {
    return "HallRecorderOptions.queue_capacity = 0: violated constraint queue_capacity > 0";
  }
  if (sink_timeout_ms <= 0) {
    return "HallRecorderOptions.sink_timeout_ms = " + std::to_string(sink_timeout_ms) +
           ": violated constraint sink_timeout_ms > 0";
  }
  if (rate_hz && *rate_hz == 0) return "HallRecorderOptions.rate_hz = 0: violated constraint > 0";
  if (settings) {
    if (std::string msg = settings->Validate(); !msg.empty()) return "HallRecorderOptions." + msg;
  }
  return {};
}

struct HallRecorder::Shared {
  HallBatchSink sink;
  std::mutex mu;
  std::condition_variable cv;
  std::deque<hall_mcu::HallBatch> queue;
  bool stop_requested = false;
  bool reader_done = false;
  bool sink_done = false;
  // When the sink call in progress started (none: the sink thread is between calls).
  std::optional<std::chrono::steady_clock::time_point> sink_call_started;
  std::string sink_error;
  HallRecorderResult result;
};

HallRecorder::HallRecorder(hall_mcu::HallSensor& sensor, HallBatchSink sink,
                           HallRecorderOptions options)
    : sensor_(sensor), options_(std::move(options)), shared_(std::make_shared<Shared>()) {
  if (std::string msg = options_.Validate(); !msg.empty()) throw std::invalid_argument(msg);
  if (!sink) throw std::invalid_argument("HallRecorder: sink is empty");
  shared_->sink = std::move(sink);
}

HallRecorder::~HallRecorder() {
  Stop();
  Wait();
}

void HallRecorder::Start() {
  if (reader_.joinable() || finished_) return;
  shared_->result.counts.driver = sensor_.counters();
  sink_thread_ = std::thread([shared = shared_] { SinkLoop(shared); });
  reader_ = std::thread([this] { ReaderLoop(); });
}

void HallRecorder::Stop() {
  std::lock_guard lock(shared_->mu);
  shared_->stop_requested = true;
  shared_->cv.notify_all();
}

HallRecorderResult HallRecorder::Wait() {
  // The reader ends within the driver's stall deadline once asked to (or by itself).
  if (reader_.joinable()) reader_.join();
  Shared& s = *shared_;
  std::unique_lock lock(s.mu);
  if (finished_ || !sink_thread_.joinable()) return s.result;
  const auto bound = std::chrono::milliseconds(options_.sink_timeout_ms);
  bool hung = false;
  while (!s.sink_done) {
    const auto now = std::chrono::steady_clock::now();
    if (s.sink_call_started && now - *s.sink_call_started >= bound) {
      hung = true;
      break;
    }
    s.cv.wait_until(lock, (s.sink_call_started ? *s.sink_call_started : now) + bound);
  }
  finished_ = true;
  if (hung) {
    s.result.end = RecorderEnd::kSinkHung;
    s.result.message = "the sink did not return within sink_timeout_ms = " +
                       std::to_string(options_.sink_timeout_ms) + " ms; its thread is abandoned";
    lock.unlock();
    sink_thread_.detach();  // it holds only `shared_` (see the header)
    lock.lock();
    return s.result;
  }
  if (!s.sink_error.empty()) {
    s.result.end = RecorderEnd::kSinkFailed;
    s.result.message = "the sink failed: " + s.sink_error;
  }
  lock.unlock();
  sink_thread_.join();
  lock.lock();
  return s.result;
}

bool HallRecorder::WaitForReader(std::chrono::milliseconds timeout) {
  std::unique_lock lock(shared_->mu);
  return shared_->cv.wait_for(lock, timeout, [&] { return shared_->reader_done; });
}

HallRecorderCounts HallRecorder::Counts() const {
  std::lock_guard lock(shared_->mu);
  return shared_->result.counts;
}

std::string HallRecorder::SinkError() const {
  std::lock_guard lock(shared_->mu);
  return shared_->sink_error;
}

bool HallRecorder::SendStartCommands(std::string* why) {
  if (!options_.control_streaming) return true;
  if (options_.rate_hz) {
    if (auto r = sensor_.SetRate(*options_.rate_hz); !r.ok) return *why = r.message, false;
  }
  if (options_.settings) {
    if (auto r = sensor_.SetSensor(*options_.settings); !r.ok) return *why = r.message, false;
  }
  if (auto r = sensor_.StartStreaming(); !r.ok) return *why = r.message, false;
  return true;
}

bool HallRecorder::TrimToDuration(hall_mcu::HallBatch* batch) {
  if (options_.max_seconds <= 0) {
    for (const auto& r : batch->readings) {
      if (!have_origin_ || r.epoch != epoch_) {
        if (have_origin_) elapsed_before_epoch_us_ += epoch_last_us_ - epoch_first_us_;
        have_origin_ = true;
        epoch_ = r.epoch;
        epoch_first_us_ = r.mcu_time_us;
      }
      epoch_last_us_ = r.mcu_time_us;
    }
    return false;
  }
  const int64_t limit_us = static_cast<int64_t>(std::llround(options_.max_seconds * 1e6));
  auto trim = [&](auto& items) -> std::optional<std::pair<uint32_t, int64_t>> {
    for (size_t i = 0; i < items.size(); ++i) {
      const auto& r = items[i];
      if (!have_origin_ || r.epoch != epoch_) {
        if (have_origin_) elapsed_before_epoch_us_ += epoch_last_us_ - epoch_first_us_;
        have_origin_ = true;
        epoch_ = r.epoch;
        epoch_first_us_ = r.mcu_time_us;
      }
      if (elapsed_before_epoch_us_ + (r.mcu_time_us - epoch_first_us_) >= limit_us) {
        const auto cut = std::make_pair(r.epoch, r.mcu_time_us);
        items.resize(i);
        return cut;
      }
      epoch_last_us_ = r.mcu_time_us;
    }
    return std::nullopt;
  };
  auto cut = !batch->readings.empty() ? trim(batch->readings) : trim(batch->marg);
  if (!cut) return false;
  auto after_cut = [&](const auto& e) {
    return e.epoch > cut->first || (e.epoch == cut->first && e.mcu_time_us >= cut->second);
  };
  std::erase_if(batch->edges, after_cut);
  std::erase_if(batch->marg, after_cut);
  return true;
}

void HallRecorder::Finish(RecorderEnd end, std::string message) {
  std::lock_guard lock(shared_->mu);
  shared_->result.end = end;
  shared_->result.message = std::move(message);
  shared_->result.counts.driver = sensor_.counters();
  shared_->reader_done = true;
  shared_->cv.notify_all();
}

void HallRecorder::ReaderLoop() {
  std::string why;
  if (!SendStartCommands(&why)) {
    Finish(RecorderEnd::kCommandFailed, why);
    return;
  }
  uint64_t resets_seen = sensor_.counters().resets;
  RecorderEnd end = RecorderEnd::kRunning;
  std::string message;
  hall_mcu::HallBatch batch;
  while (end == RecorderEnd::kRunning) {
    {
      std::lock_guard lock(shared_->mu);
      if (shared_->stop_requested) {
        end = RecorderEnd::kStopped;
        break;
      }
    }
    batch.clear();
    const hall_mcu::ReadResult read = sensor_.Read(&batch);
    const bool limit = TrimToDuration(&batch);
    const bool end_of_data = batch.end_of_data;
    const hall_mcu::HallCounters counters = sensor_.counters();
    {
      std::lock_guard lock(shared_->mu);
      HallRecorderCounts& c = shared_->result.counts;
      c.driver = counters;
      c.seconds_recorded = (elapsed_before_epoch_us_ + (epoch_last_us_ - epoch_first_us_)) * 1e-6;
      if (!batch.empty()) {
        // A failed sink takes nothing more: what it would have been given is dropped.
        if (shared_->queue.size() >= options_.queue_capacity || !shared_->sink_error.empty()) {
          ++c.batches_dropped;
          c.readings_dropped += batch.readings.size();
        } else {
          c.readings_delivered += batch.readings.size();
          c.edges_delivered += batch.edges.size();
          c.marg_delivered += batch.marg.size();
          shared_->queue.push_back(std::move(batch));
          batch = hall_mcu::HallBatch{};
          shared_->cv.notify_all();
        }
      }
    }
    if (limit) {
      end = RecorderEnd::kDuration;
      message = "recorded " + std::to_string(options_.max_seconds) + " s";
    } else if (read.status == hall_mcu::ReadStatus::kClosed) {
      end = RecorderEnd::kClosed;
      message = read.message;
    } else if (read.status == hall_mcu::ReadStatus::kStall && options_.stop_on_stall) {
      end = RecorderEnd::kStall;
      message = read.message;
    } else if (end_of_data && options_.stop_on_end_of_data) {
      end = RecorderEnd::kEndOfData;
      message = "the MCU reported the end of its data";
    } else if (counters.resets > resets_seen) {
      resets_seen = counters.resets;
      if (!SendStartCommands(&why)) {
        end = RecorderEnd::kCommandFailed;
        message = "after an MCU reset: " + why;
      }
    }
  }
  if (options_.control_streaming && end != RecorderEnd::kClosed) {
    sensor_.StopStreaming();  // best effort; the result already says why we ended
  }
  Finish(end, message);
}

void HallRecorder::SinkLoop(const std::shared_ptr<Shared>& shared) {
  Shared& s = *shared;
  std::unique_lock lock(s.mu);
  while (true) {
    s.cv.wait(lock, [&] { return !s.queue.empty() || s.reader_done; });
    if (s.queue.empty() && s.reader_done) break;
    hall_mcu::HallBatch batch = std::move(s.queue.front());
    s.queue.pop_front();
    s.sink_call_started = std::chrono::steady_clock::now();
    lock.unlock();
    std::string error;
    try {
      s.sink(batch);
    } catch (const std::exception& e) {
      error = e.what();
      if (error.empty()) error = "exception without a message";
    } catch (...) {
      error = "unknown exception";
    }
    lock.lock();
    s.sink_call_started.reset();
    if (!error.empty()) {
      // Stop the recording; the failed batch and everything still queued are lost to the sink.
      s.sink_error = error;
      s.stop_requested = true;
      HallRecorderCounts& c = s.result.counts;
      auto drop = [&c](const hall_mcu::HallBatch& b) {
        ++c.batches_dropped;
        c.readings_dropped += b.readings.size();
        c.readings_delivered -= b.readings.size();
        c.edges_delivered -= b.edges.size();
        c.marg_delivered -= b.marg.size();
      };
      drop(batch);
      for (const auto& b : s.queue) drop(b);
      s.queue.clear();
      s.cv.notify_all();
      break;
    }
    s.cv.notify_all();  // Wait() watches the progress of the sink
  }
  s.sink_done = true;
  s.cv.notify_all();
}

}  // namespace msmcal::acquisition
