#include "mocks/mcu/mock_mcu.h"

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>

namespace msmcal::sim {

using hall_mcu::Frame;
using hall_mcu::FrameType;

// "flip@1200", "drop@300", "reset@5000", "stall@9000" or "stall@9000:2000" (ms).
McuFault ParseMcuFault(const std::string& text) {
  const size_t at = text.find('@');
  if (at == std::string::npos) {
    throw std::runtime_error("--fault '" + text + "': expected KIND@FRAME, e.g. flip@1200");
  }
  const std::string kind = text.substr(0, at);
  McuFault fault;
  if (kind == "flip") {
    fault.kind = McuFaultKind::kFlipBit;
  } else if (kind == "drop") {
    fault.kind = McuFaultKind::kDropByte;
  } else if (kind == "reset") {
    fault.kind = McuFaultKind::kReset;
  } else if (kind == "stall") {
    fault.kind = McuFaultKind::kStall;
  } else {
    throw std::runtime_error("--fault '" + text + "': kind must be flip|drop|reset|stall");
  }
  std::string rest = text.substr(at + 1);
  try {
    const size_t colon = rest.find(':');
    if (colon != std::string::npos) {
      fault.stall_ms = std::stoll(rest.substr(colon + 1));
      rest = rest.substr(0, colon);
    }
    fault.data_frame = std::stoull(rest);
  } catch (const std::exception&) {
    throw std::runtime_error("--fault '" + text + "': FRAME must be a non-negative integer");
  }
  return fault;
}

std::string MockMcuOptions::Validate() const {
  if (!(speed >= 0)) {
    return "MockMcuOptions.speed = " + std::to_string(speed) + ": violated constraint speed >= 0";
  }
  if (rate_hz == 0) return "MockMcuOptions.rate_hz = 0: violated constraint rate_hz > 0";
  if (heartbeat_period_us < 0) {
    return "MockMcuOptions.heartbeat_period_us = " + std::to_string(heartbeat_period_us) +
           ": violated constraint >= 0";
  }
  if (std::string msg = settings.Validate(); !msg.empty()) return "MockMcuOptions." + msg;
  return {};
}

MockMcu::MockMcu(const MockMcuOptions& options, std::unique_ptr<McuDataSource> source)
    : options_(options), source_(std::move(source)), rng_(options.seed) {
  if (std::string msg = options.Validate(); !msg.empty()) throw std::runtime_error(msg);
  if (!source_) throw std::runtime_error("MockMcu: no data source");
  termios tio{};
  cfmakeraw(&tio);
  char name[256] = {};
  if (openpty(&master_fd_, &slave_fd_, name, &tio, nullptr) != 0) {
    throw std::runtime_error(std::string("MockMcu: openpty failed: ") + std::strerror(errno));
  }
  slave_path_ = name;
  fcntl(master_fd_, F_SETFL, fcntl(master_fd_, F_GETFL) | O_NONBLOCK);
  fcntl(master_fd_, F_SETFD, FD_CLOEXEC);
  fcntl(slave_fd_, F_SETFD, FD_CLOEXEC);
  if (pipe2(stop_pipe_, O_CLOEXEC | O_NONBLOCK) != 0) {
    throw std::runtime_error(std::string("MockMcu: pipe failed: ") + std::strerror(errno));
  }
  if (!options_.link_path.empty()) {
    struct stat st {};
    if (lstat(options_.link_path.c_str(), &st) == 0) {
      if (!S_ISLNK(st.st_mode)) {
        throw std::runtime_error("MockMcu: " + options_.link_path +
                                 " exists and is not a symlink; refusing to replace it");
      }
      unlink(options_.link_path.c_str());
    }
    if (symlink(slave_path_.c_str(), options_.link_path.c_str()) != 0) {
      throw std::runtime_error("MockMcu: cannot create symlink " + options_.link_path + ": " +
                               std::strerror(errno));
    }
  }
  faults_ = options_.faults;
  std::stable_sort(faults_.begin(), faults_.end(),
                   [](const McuFault& a, const McuFault& b) { return a.data_frame < b.data_frame; });
  settings_ = options_.settings;
  rate_hz_ = options_.rate_hz;
}

MockMcu::~MockMcu() {
  Stop();
  if (!options_.link_path.empty()) unlink(options_.link_path.c_str());
  for (int fd : {master_fd_, slave_fd_, stop_pipe_[0], stop_pipe_[1]}) {
    if (fd >= 0) close(fd);
  }
}

void MockMcu::Start() {
  if (thread_.joinable()) return;
  thread_ = std::thread([this] { Loop(); });
}

void MockMcu::Stop() {
  stop_ = true;
  const char c = 1;
  [[maybe_unused]] ssize_t n = write(stop_pipe_[1], &c, 1);
  if (thread_.joinable()) thread_.join();
  std::lock_guard lock(mu_);
  exhausted_cv_.notify_all();
}

bool MockMcu::WaitUntilExhausted() {
  std::unique_lock lock(mu_);
  exhausted_cv_.wait(lock, [&] { return log_.source_exhausted || stop_.load(); });
  return log_.source_exhausted;
}

MockMcuLog MockMcu::Log() const {
  std::lock_guard lock(mu_);
  return log_;
}

int64_t MockMcu::NowNs() const {
  if (options_.now_ns) return options_.now_ns();
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

bool MockMcu::WaitFor(int64_t wait_ms) {
  pollfd fds[2] = {{stop_pipe_[0], POLLIN, 0}, {master_fd_, POLLIN, 0}};
  poll(fds, 2, static_cast<int>(std::clamp<int64_t>(wait_ms, 0, 1000)));
  return !stop_;
}

bool MockMcu::WriteBytes(const std::vector<uint8_t>& bytes) {
  size_t done = 0;
  while (done < bytes.size()) {
    if (stop_) return false;
    const ssize_t n = write(master_fd_, bytes.data() + done, bytes.size() - done);
    if (n > 0) {
      done += static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EINTR) return false;
    pollfd fds[2] = {{stop_pipe_[0], POLLIN, 0}, {master_fd_, POLLOUT, 0}};
    poll(fds, 2, 100);
  }
  return true;
}

bool MockMcu::Flush() {
  if (out_.empty()) return !stop_;
  const bool ok = WriteBytes(out_);
  out_.clear();
  return ok;
}

void MockMcu::EmitStatus(uint8_t extra_flags) {
  hall_mcu::StatusPayload s;
  s.flags = static_cast<uint8_t>(extra_flags | (streaming_ ? hall_mcu::kStatusStreaming : 0));
  s.rate_hz = rate_hz_;
  s.next_reading_seq = reading_seq_;
  s.next_edge_seq = edge_seq_;
  s.next_marg_seq = marg_seq_;
  Frame f{FrameType::kStatus, status_seq_++, last_event_time_us_ - boot_time_us_,
          hall_mcu::EncodeStatus(s)};
  hall_mcu::EncodeFrame(f, &out_);
}

void MockMcu::Boot() {
  reading_seq_ = edge_seq_ = marg_seq_ = status_seq_ = 0;
  boot_time_us_ = last_event_time_us_;
  settings_ = options_.settings;
  rate_hz_ = options_.rate_hz;
  streaming_ = false;
  next_heartbeat_us_ = last_event_time_us_ + options_.heartbeat_period_us;
  EmitStatus(hall_mcu::kStatusBoot);
}

void MockMcu::HandleCommands() {
  uint8_t buf[512];
  while (true) {
    const ssize_t n = read(master_fd_, buf, sizeof(buf));
    if (n <= 0) break;
    commands_.Feed(std::span<const uint8_t>(buf, static_cast<size_t>(n)));
  }
  while (std::optional<Frame> cmd = commands_.Next()) {
    if (static_cast<uint8_t>(cmd->type) < 0x80) continue;  // not a command
    hall_mcu::ReplyPayload reply;
    reply.command = static_cast<uint8_t>(cmd->type);
    bool status_after = false;
    switch (cmd->type) {
      case FrameType::kIdentify:
        reply.data = hall_mcu::EncodeIdentify(options_.identify);
        break;
      case FrameType::kStartStreaming:
        streaming_ = true;
        break;
      case FrameType::kStopStreaming:
        streaming_ = false;
        break;
      case FrameType::kSetRate: {
        std::optional<uint16_t> rate = hall_mcu::DecodeRate(cmd->payload);
        if (!rate || *rate == 0 || *rate > 5000) {
          reply.result = hall_mcu::ReplyResult::kBadValue;
        } else {
          rate_hz_ = *rate;
        }
        break;
      }
      case FrameType::kSetSensor: {
        std::optional<hall_mcu::SensorSettings> s = hall_mcu::DecodeSensorSettings(cmd->payload);
        if (!s) {
          reply.result = hall_mcu::ReplyResult::kBadValue;
        } else {
          settings_ = *s;
        }
        break;
      }
      case FrameType::kGetStatus:
        status_after = true;
        break;
      default:
        reply.result = hall_mcu::ReplyResult::kUnsupported;
        break;
    }
    // A requested status frame goes out before the reply, so the host has it when the command
    // completes.
    if (status_after) EmitStatus(0);
    Frame f{FrameType::kCommandReply, cmd->seq, last_event_time_us_ - boot_time_us_,
            hall_mcu::EncodeReply(reply)};
    hall_mcu::EncodeFrame(f, &out_);
    {
      std::lock_guard lock(mu_);
      ++log_.commands;
    }
    Flush();
  }
}

void MockMcu::EmitData(const McuEvent& event) {
  last_event_time_us_ = std::max(last_event_time_us_, event.time_us);
  const int64_t t_us = event.time_us - boot_time_us_;
  Frame f;
  f.mcu_time_us = t_us;
  hall_mcu::HallSample sample;
  switch (event.kind) {
    case McuEvent::Kind::kField: {
      hall_mcu::FieldPayload p;
      p.gain_sel = settings_.gain_sel;
      p.res_x = settings_.res_x;
      p.res_y = settings_.res_y;
      p.res_z = settings_.res_z;
      p.reg_x = hall_mcu::MicroteslaToRegister(event.field_uT[0], hall_mcu::Axis::kX, p.gain_sel,
                                               p.res_x);
      p.reg_y = hall_mcu::MicroteslaToRegister(event.field_uT[1], hall_mcu::Axis::kY, p.gain_sel,
                                               p.res_y);
      p.reg_z = hall_mcu::MicroteslaToRegister(event.field_uT[2], hall_mcu::Axis::kZ, p.gain_sel,
                                               p.res_z);
      f.type = FrameType::kFieldReading;
      f.seq = reading_seq_++;
      f.payload = hall_mcu::EncodeField(p);
      sample.seq = f.seq;
      sample.mcu_time_us = t_us;
      sample.reg_x = p.reg_x;
      sample.reg_y = p.reg_y;
      sample.reg_z = p.reg_z;
      sample.gain_sel = p.gain_sel;
      sample.res_x = p.res_x;
      sample.res_y = p.res_y;
      sample.res_z = p.res_z;
      sample.bx_uT =
          hall_mcu::RegisterToMicrotesla(p.reg_x, hall_mcu::Axis::kX, p.gain_sel, p.res_x);
      sample.by_uT =
          hall_mcu::RegisterToMicrotesla(p.reg_y, hall_mcu::Axis::kY, p.gain_sel, p.res_y);
      sample.bz_uT =
          hall_mcu::RegisterToMicrotesla(p.reg_z, hall_mcu::Axis::kZ, p.gain_sel, p.res_z);
      break;
    }
    case McuEvent::Kind::kClockEdge:
      f.type = FrameType::kClockEdge;
      f.seq = edge_seq_++;
      break;
    case McuEvent::Kind::kMarg: {
      hall_mcu::MargPayload p;
      for (int i = 0; i < 3; ++i) {
        p.accel_g[i] = static_cast<float>(event.accel_g[i]);
        p.gyro_dps[i] = static_cast<float>(event.gyro_dps[i]);
        p.mag_uT[i] = static_cast<float>(event.mag_uT[i]);
      }
      f.type = FrameType::kMargReading;
      f.seq = marg_seq_++;
      f.payload = hall_mcu::EncodeMarg(p);
      break;
    }
  }
  std::vector<uint8_t> bytes = hall_mcu::EncodeFrame(f);

  const McuFault* fault = nullptr;
  while (next_fault_ < faults_.size() && faults_[next_fault_].data_frame < data_frames_) {
    ++next_fault_;  // a second fault on an already-handled frame is ignored
  }
  if (next_fault_ < faults_.size() && faults_[next_fault_].data_frame == data_frames_) {
    fault = &faults_[next_fault_++];
  }
  ++data_frames_;

  auto damaged = [&](MockMcuLog& log) -> std::vector<uint32_t>& {
    return f.type == FrameType::kFieldReading ? log.damaged_reading_seqs
           : f.type == FrameType::kClockEdge  ? log.damaged_edge_seqs
                                              : log.damaged_marg_seqs;
  };
  bool intact = true;
  if (fault != nullptr) {
    switch (fault->kind) {
      case McuFaultKind::kStall: {
        Flush();
        {
          std::lock_guard lock(mu_);
          ++log_.stalls;
        }
        const int64_t until = NowNs() + fault->stall_ms * 1000000;
        while (!stop_ && (fault->stall_ms < 0 || NowNs() < until)) {
          pollfd fd{stop_pipe_[0], POLLIN, 0};
          poll(&fd, 1, 50);
        }
        break;
      }
      case McuFaultKind::kFlipBit: {
        const size_t bit = rng_() % (bytes.size() * 8);
        bytes[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
        intact = false;
        std::lock_guard lock(mu_);
        ++log_.flipped_bits;
        damaged(log_).push_back(f.seq);
        break;
      }
      case McuFaultKind::kDropByte: {
        bytes.erase(bytes.begin() + static_cast<long>(rng_() % bytes.size()));
        intact = false;
        std::lock_guard lock(mu_);
        ++log_.dropped_bytes;
        damaged(log_).push_back(f.seq);
        break;
      }
      case McuFaultKind::kReset: {
        bytes.resize(1 + rng_() % (bytes.size() - 1));
        out_.insert(out_.end(), bytes.begin(), bytes.end());
        Flush();
        {
          std::lock_guard lock(mu_);
          ++log_.resets;
          if (f.type == FrameType::kFieldReading) log_.truncated_reading_seqs.push_back(f.seq);
          if (f.type == FrameType::kClockEdge) log_.truncated_edge_seqs.push_back(f.seq);
          if (f.type == FrameType::kFieldReading) ++log_.readings_sent_total;
        }
        Boot();
        Flush();
        return;
      }
    }
  }
  {
    std::lock_guard lock(mu_);
    if (f.type == FrameType::kFieldReading) {
      ++log_.readings_sent_total;
      if (intact && options_.record_sent) {
        sample.epoch = static_cast<uint32_t>(log_.resets);
        log_.sent_readings.push_back(sample);
      }
    } else if (f.type == FrameType::kClockEdge && intact && options_.record_sent) {
      log_.sent_edges.push_back(
          hall_mcu::ClockEdge{static_cast<uint32_t>(log_.resets), f.seq, t_us});
    } else if (f.type == FrameType::kMargReading && intact) {
      ++log_.sent_marg;
    }
  }
  out_.insert(out_.end(), bytes.begin(), bytes.end());
}

void MockMcu::Loop() {
  // Power-up: boot status (waits in the pty buffer until the host opens the device).
  Boot();
  streaming_ = options_.stream_on_open;
  Flush();
  const bool pacing = options_.speed > 0;
  bool was_streaming = false;
  int64_t wall_start_ns = 0;
  int64_t src_start_us = 0;
  bool exhausted = false;
  std::optional<McuEvent> next;
  while (!stop_) {
    HandleCommands();
    if (!streaming_ || exhausted) {
      was_streaming = false;
      if (!Flush()) break;
      WaitFor(20);
      continue;
    }
    if (!next) {
      next = source_->Next();
      if (!next) {
        exhausted = true;
        EmitStatus(hall_mcu::kStatusEndOfData);
        Flush();
        std::lock_guard lock(mu_);
        log_.source_exhausted = true;
        exhausted_cv_.notify_all();
        continue;
      }
    }
    if (pacing) {
      if (!was_streaming) {
        wall_start_ns = NowNs();
        src_start_us = next->time_us;
      }
      const int64_t due_ns = wall_start_ns + static_cast<int64_t>((next->time_us - src_start_us) *
                                                                  1000.0 / options_.speed);
      const int64_t now = NowNs();
      if (now < due_ns) {
        was_streaming = true;
        if (!Flush()) break;
        WaitFor(std::min<int64_t>((due_ns - now) / 1000000 + 1, 20));
        continue;
      }
    }
    was_streaming = true;
    if (options_.heartbeat_period_us > 0 && next->time_us >= next_heartbeat_us_) {
      last_event_time_us_ = std::max(last_event_time_us_, next->time_us);
      EmitStatus(0);
      next_heartbeat_us_ = next->time_us + options_.heartbeat_period_us;
    }
    EmitData(*next);
    next.reset();
    if (out_.size() >= 4096 && !Flush()) break;
  }
}

}  // namespace msmcal::sim
