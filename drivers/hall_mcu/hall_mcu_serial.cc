// The Hall MCU driver over a Boost.Asio serial port. Asio stays in this file (the factory returns
// the abstract HallSensor).
#include <boost/asio/io_context.hpp>
#include <boost/asio/serial_port.hpp>
#include <boost/asio/write.hpp>
#include <chrono>
#include <stdexcept>
#include <utility>

#include "drivers/hall_mcu/decoder.h"
#include "drivers/hall_mcu/hall_sensor.h"

namespace msmcal::hall_mcu {

std::string DeviceInfo::ToString() const {
  std::string type = identify.sensor_type == SensorType::kMlx90393 ? "MLX90393"
                     : identify.sensor_type == SensorType::kMarg   ? "MARG"
                                                                   : "unknown";
  return identify.board + " firmware " + std::to_string(identify.fw_major) + "." +
         std::to_string(identify.fw_minor) + "." + std::to_string(identify.fw_patch) + " sensor " +
         type;
}

const char* ToString(ReadStatus status) {
  switch (status) {
    case ReadStatus::kOk:
      return "ok";
    case ReadStatus::kStall:
      return "stall";
    case ReadStatus::kClosed:
      return "closed";
  }
  return "unknown";
}

std::string HallMcuOptions::Validate() const {
  if (device.empty()) return "HallMcuOptions.device is empty: violated constraint non-empty path";
  if (baud_rate == 0) return "HallMcuOptions.baud_rate = 0: violated constraint baud_rate > 0";
  if (stall_timeout_ms <= 0) {
    return "HallMcuOptions.stall_timeout_ms = " + std::to_string(stall_timeout_ms) +
           ": violated constraint stall_timeout_ms > 0";
  }
  if (command_timeout_ms <= 0) {
    return "HallMcuOptions.command_timeout_ms = " + std::to_string(command_timeout_ms) +
           ": violated constraint command_timeout_ms > 0";
  }
  return {};
}

namespace {

namespace asio = boost::asio;
using Clock = std::chrono::steady_clock;
using boost::system::error_code;

class SerialHallMcu final : public HallSensor {
 public:
  explicit SerialHallMcu(const HallMcuOptions& options) : options_(options), port_(io_) {
    error_code ec;
    port_.open(options.device, ec);  // Asio puts the tty in raw mode on open
    if (ec) {
      throw std::runtime_error("hall mcu: cannot open " + options.device + ": " + ec.message());
    }
    // Each option is checked on its own: one error code for all would keep only the last one.
    auto set = [&](const auto& option, const std::string& what) {
      error_code e;
      port_.set_option(option, e);
      if (e) {
        throw std::runtime_error("hall mcu: cannot configure " + options.device + ": " + what +
                                 ": " + e.message());
      }
    };
    set(asio::serial_port_base::baud_rate(options.baud_rate),
        "baud_rate " + std::to_string(options.baud_rate));
    set(asio::serial_port_base::character_size(8), "8 data bits");
    set(asio::serial_port_base::parity(asio::serial_port_base::parity::none), "no parity");
    set(asio::serial_port_base::stop_bits(asio::serial_port_base::stop_bits::one), "1 stop bit");
    set(asio::serial_port_base::flow_control(asio::serial_port_base::flow_control::none),
        "no flow control");
  }

  CommandResult Identify(DeviceInfo* info) override {
    ReplyPayload reply;
    CommandResult r = Command(FrameType::kIdentify, {}, &reply);
    if (!r.ok) return r;
    std::optional<IdentifyInfo> id = DecodeIdentify(reply.data);
    if (!id)
      return CommandResult::Error(
          "identify: malformed reply data (" + std::to_string(reply.data.size()) + " bytes)",
          StatusCode::kProtocol);
    if (info != nullptr) info->identify = *id;
    return r;
  }
  CommandResult StartStreaming() override { return Command(FrameType::kStartStreaming, {}); }
  CommandResult StopStreaming() override { return Command(FrameType::kStopStreaming, {}); }
  CommandResult SetRate(uint16_t rate_hz) override {
    return Command(FrameType::kSetRate, EncodeRate(rate_hz));
  }
  CommandResult SetSensor(const SensorSettings& settings) override {
    if (std::string msg = settings.Validate(); !msg.empty())
      return CommandResult::Error("set_sensor: " + msg, StatusCode::kRefused);
    return Command(FrameType::kSetSensor, EncodeSensorSettings(settings));
  }
  CommandResult RequestStatus() override { return Command(FrameType::kGetStatus, {}); }

  ReadResult Read(HallBatch* batch) override {
    const auto has_news = [&] { return !batch->empty() || batch->end_of_data || batch->mcu_reset; };
    MovePending(batch);
    Drain(batch, /*wanted_seq=*/nullptr, nullptr);
    if (has_news()) return {};
    const auto deadline = Clock::now() + std::chrono::milliseconds(options_.stall_timeout_ms);
    while (true) {
      error_code ec;
      bool timed_out = false;
      const size_t n = ReadSome(deadline, &ec, &timed_out);
      if (n > 0) {
        decoder_.Feed(std::span<const uint8_t>(rx_.data(), n));
        Drain(batch, nullptr, nullptr);
        if (has_news()) return {};
        continue;
      }
      if (timed_out) {
        ++stalls_;
        return {ReadStatus::kStall, "hall mcu: no complete frame from " + options_.device +
                                        " within " + std::to_string(options_.stall_timeout_ms) +
                                        " ms"};
      }
      if (ec) return {ReadStatus::kClosed, "hall mcu: " + options_.device + ": " + ec.message()};
    }
  }

  const HallCounters& counters() const override {
    merged_ = tracker_.counters();
    merged_.crc_errors = decoder_.counters().crc_errors;
    merged_.bad_headers = decoder_.counters().bad_headers;
    merged_.bytes_discarded = decoder_.counters().bytes_discarded;
    merged_.stalls = stalls_;
    return merged_;
  }

 private:
  // Reads whatever is available before `deadline`. Returns the byte count (0 with *timed_out on
  // deadline, 0 with *ec on EOF / I/O error).
  size_t ReadSome(Clock::time_point deadline, error_code* ec, bool* timed_out) {
    const auto remaining = deadline - Clock::now();
    if (remaining <= Clock::duration::zero()) {
      *timed_out = true;
      return 0;
    }
    bool done = false;
    size_t n = 0;
    port_.async_read_some(asio::buffer(rx_), [&](const error_code& e, size_t k) {
      *ec = e;
      n = k;
      done = true;
    });
    io_.restart();
    io_.run_for(remaining);
    if (!done) {
      port_.cancel();
      io_.restart();
      io_.run();  // completes the cancelled read
    }
    if (n == 0 && (!done || *ec == asio::error::operation_aborted)) {
      *timed_out = true;
      *ec = {};
    } else if (n > 0) {
      *ec = {};
    }
    return n;
  }

  bool WriteAll(const std::vector<uint8_t>& bytes, Clock::time_point deadline, std::string* why) {
    bool done = false;
    error_code ec;
    asio::async_write(port_, asio::buffer(bytes), [&](const error_code& e, size_t) {
      ec = e;
      done = true;
    });
    io_.restart();
    io_.run_for(std::max(Clock::duration::zero(), deadline - Clock::now()));
    if (!done) {
      port_.cancel();
      io_.restart();
      io_.run();
      *why = "write timed out";
      return false;
    }
    if (ec) {
      *why = ec.message();
      return false;
    }
    return true;
  }

  // Decodes every buffered frame: data frames go to *batch, a reply whose seq equals *wanted_seq is
  // stored in *reply (and *wanted_seq cleared); other replies are stale and dropped.
  void Drain(HallBatch* batch, const uint32_t* wanted_seq, std::optional<ReplyPayload>* reply) {
    while (std::optional<Frame> frame = decoder_.Next()) {
      if (frame->type == FrameType::kCommandReply) {
        if (wanted_seq != nullptr && reply != nullptr && !reply->has_value() &&
            frame->seq == *wanted_seq) {
          *reply = DecodeReply(frame->payload);
        }
        continue;
      }
      tracker_.Accept(*frame, batch);
    }
  }

  void MovePending(HallBatch* batch) {
    if (pending_.empty() && !pending_.end_of_data && !pending_.mcu_reset) return;
    batch->readings.insert(batch->readings.end(), pending_.readings.begin(),
                           pending_.readings.end());
    batch->edges.insert(batch->edges.end(), pending_.edges.begin(), pending_.edges.end());
    batch->marg.insert(batch->marg.end(), pending_.marg.begin(), pending_.marg.end());
    batch->end_of_data = batch->end_of_data || pending_.end_of_data;
    batch->mcu_reset = batch->mcu_reset || pending_.mcu_reset;
    pending_.clear();
  }

  CommandResult Command(FrameType type, std::vector<uint8_t> payload, ReplyPayload* out = nullptr) {
    const char* name = ToString(type);
    const uint32_t seq = next_command_seq_++;
    Frame frame{type, seq, /*mcu_time_us=*/0, std::move(payload)};
    const auto deadline = Clock::now() + std::chrono::milliseconds(options_.command_timeout_ms);
    std::string why;
    if (!WriteAll(EncodeFrame(frame), deadline, &why)) {
      return CommandResult::Error(
          std::string(name) + ": cannot write to " + options_.device + ": " + why,
          StatusCode::kUnavailable);
    }
    std::optional<ReplyPayload> reply;
    Drain(&pending_, &seq, &reply);
    while (!reply) {
      error_code ec;
      bool timed_out = false;
      const size_t n = ReadSome(deadline, &ec, &timed_out);
      if (n > 0) {
        decoder_.Feed(std::span<const uint8_t>(rx_.data(), n));
        Drain(&pending_, &seq, &reply);
      } else if (timed_out) {
        return CommandResult::Error(std::string(name) + ": no reply from " + options_.device +
                                        " within " + std::to_string(options_.command_timeout_ms) +
                                        " ms",
                                    StatusCode::kTimeout);
      } else if (ec) {
        return CommandResult::Error(
            std::string(name) + ": " + options_.device + ": " + ec.message(),
            StatusCode::kUnavailable);
      }
    }
    if (reply->command != static_cast<uint8_t>(type)) {
      return CommandResult::Error(
          std::string(name) + ": reply names command " + std::to_string(reply->command),
          StatusCode::kProtocol);
    }
    if (reply->result != ReplyResult::kOk) {
      return CommandResult::Error(
          std::string(name) + ": rejected by the MCU: " + ToString(reply->result),
          StatusCode::kDeviceError);
    }
    if (out != nullptr) *out = std::move(*reply);
    return {};
  }

  HallMcuOptions options_;
  asio::io_context io_;
  asio::serial_port port_;
  std::array<uint8_t, 4096> rx_{};
  FrameDecoder decoder_;
  StreamTracker tracker_;
  HallBatch pending_;  // data that arrived while waiting for a command reply
  uint32_t next_command_seq_ = 1;
  uint64_t stalls_ = 0;
  mutable HallCounters merged_;
};

}  // namespace

std::unique_ptr<HallSensor> OpenHallMcu(const HallMcuOptions& options) {
  if (std::string msg = options.Validate(); !msg.empty()) {
    throw std::runtime_error("hall mcu: invalid options: " + msg);
  }
  return std::make_unique<SerialHallMcu>(options);
}

}  // namespace msmcal::hall_mcu
