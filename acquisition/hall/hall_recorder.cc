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
  if (rate_hz && *rate_hz == 0) return "HallRecorderOptions.rate_hz = 0: violated constraint > 0";
  if (settings) {
    if (std::string msg = settings->Validate(); !msg.empty()) return "HallRecorderOptions." + msg;
  }
  return {};
}

HallRecorder::HallRecorder(hall_mcu::HallSensor& sensor, HallBatchSink sink,
                           HallRecorderOptions options)
    : sensor_(sensor), sink_(std::move(sink)), options_(std::move(options)) {
  if (std::string msg = options_.Validate(); !msg.empty()) throw std::invalid_argument(msg);
  if (!sink_) throw std::invalid_argument("HallRecorder: sink is empty");
}

HallRecorder::~HallRecorder() {
  Stop();
  Wait();
}

void HallRecorder::Start() {
  if (reader_.joinable()) return;
  result_.counts.driver = sensor_.counters();
  sink_thread_ = std::thread([this] { SinkLoop(); });
  reader_ = std::thread([this] { ReaderLoop(); });
}

void HallRecorder::Stop() {
  std::lock_guard lock(mu_);
  stop_requested_ = true;
  cv_.notify_all();
}

HallRecorderResult HallRecorder::Wait() {
  if (reader_.joinable()) reader_.join();
  if (sink_thread_.joinable()) sink_thread_.join();
  std::lock_guard lock(mu_);
  return result_;
}

bool HallRecorder::WaitForReader(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mu_);
  return cv_.wait_for(lock, timeout, [&] { return reader_done_; });
}

HallRecorderCounts HallRecorder::Counts() const {
  std::lock_guard lock(mu_);
  return result_.counts;
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
  std::lock_guard lock(mu_);
  result_.end = end;
  result_.message = std::move(message);
  result_.counts.driver = sensor_.counters();
  reader_done_ = true;
  cv_.notify_all();
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
      std::lock_guard lock(mu_);
      if (stop_requested_) {
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
      std::lock_guard lock(mu_);
      HallRecorderCounts& c = result_.counts;
      c.driver = counters;
      c.seconds_recorded = (elapsed_before_epoch_us_ + (epoch_last_us_ - epoch_first_us_)) * 1e-6;
      if (!batch.empty()) {
        if (queue_.size() >= options_.queue_capacity) {
          ++c.batches_dropped;
          c.readings_dropped += batch.readings.size();
        } else {
          c.readings_delivered += batch.readings.size();
          c.edges_delivered += batch.edges.size();
          c.marg_delivered += batch.marg.size();
          queue_.push_back(std::move(batch));
          batch = hall_mcu::HallBatch{};
          cv_.notify_all();
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

void HallRecorder::SinkLoop() {
  std::unique_lock lock(mu_);
  while (true) {
    cv_.wait(lock, [&] { return !queue_.empty() || reader_done_; });
    if (queue_.empty() && reader_done_) return;
    hall_mcu::HallBatch batch = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    sink_(batch);
    lock.lock();
  }
}

}  // namespace msmcal::acquisition
