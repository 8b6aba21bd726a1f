#include "drivers/hall_mcu/decoder.h"

#include <algorithm>
#include <cstring>

namespace msmcal::hall_mcu {
namespace {

uint32_t GetU32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}
uint64_t GetU64(const uint8_t* p) {
  return static_cast<uint64_t>(GetU32(p)) | (static_cast<uint64_t>(GetU32(p + 4)) << 32);
}

// A forward difference a - b in sequence space; "ahead" when in (0, 2^31).
bool Ahead(uint32_t a, uint32_t b, uint32_t* gap) {
  *gap = a - b;
  return *gap != 0 && *gap < 0x80000000u;
}

}  // namespace

void FrameDecoder::Feed(std::span<const uint8_t> bytes) {
  if (head_ > 0 && (head_ >= 4096 || head_ * 2 >= buf_.size())) {
    buf_.erase(buf_.begin(), buf_.begin() + static_cast<long>(head_));
    head_ = 0;
  }
  buf_.insert(buf_.end(), bytes.begin(), bytes.end());
}

void FrameDecoder::Discard(size_t n) {
  head_ += n;
  counters_.bytes_discarded += n;
}

std::optional<Frame> FrameDecoder::Next() {
  while (true) {
    const size_t avail = buf_.size() - head_;
    if (avail == 0) return std::nullopt;
    const uint8_t* p = buf_.data() + head_;
    if (p[0] != kSync0) {
      // Skip to the next possible sync byte in one step.
      const void* hit = std::memchr(p + 1, kSync0, avail - 1);
      Discard(hit == nullptr ? avail : static_cast<size_t>(static_cast<const uint8_t*>(hit) - p));
      continue;
    }
    if (avail < 2) return std::nullopt;
    if (p[1] != kSync1) {
      Discard(1);
      continue;
    }
    if (avail < 4) return std::nullopt;
    const size_t length = p[2];
    bool fixed = true;
    const std::optional<size_t> expected = PayloadSize(p[3], &fixed);
    if (!expected || (fixed && length != *expected) || (!fixed && length > *expected)) {
      ++counters_.bad_headers;
      Discard(1);
      continue;
    }
    const size_t total = kHeaderSize + length + kCrcSize;
    if (avail < total) return std::nullopt;
    const uint16_t crc = Crc16(std::span<const uint8_t>(p + 2, kHeaderSize - 2 + length));
    const uint16_t wire_crc =
        static_cast<uint16_t>(p[kHeaderSize + length] | (p[kHeaderSize + length + 1] << 8));
    if (crc != wire_crc) {
      ++counters_.crc_errors;
      Discard(1);
      continue;
    }
    Frame frame;
    frame.type = static_cast<FrameType>(p[3]);
    frame.seq = GetU32(p + 4);
    frame.mcu_time_us = static_cast<int64_t>(GetU64(p + 8));
    frame.payload.assign(p + kHeaderSize, p + kHeaderSize + length);
    head_ += total;
    ++counters_.frames;
    return frame;
  }
}

void StreamTracker::OnReset() {
  ++epoch_;
  ++counters_.resets;
  for (Stream& s : streams_) s = Stream{.seq_known = true, .expected_seq = 0};
}

void StreamTracker::Sequence(int stream, uint32_t seq, uint64_t* lost) {
  Stream& s = streams_[stream];
  uint32_t gap = 0;
  if (s.seq_known && Ahead(seq, s.expected_seq, &gap) && lost != nullptr) *lost += gap;
  s.seq_known = true;
  s.expected_seq = seq + 1;
}

void StreamTracker::CatchUp(int stream, uint32_t next_seq, uint64_t* lost) {
  Stream& s = streams_[stream];
  uint32_t gap = 0;
  if (s.seq_known && Ahead(next_seq, s.expected_seq, &gap)) *lost += gap;
  if (!s.seq_known || gap != 0) {
    s.seq_known = true;
    s.expected_seq = next_seq;
  }
}

bool StreamTracker::Accept(const Frame& frame, HallBatch* out) {
  int stream = -1;
  switch (frame.type) {
    case FrameType::kFieldReading:
      stream = kReadings;
      break;
    case FrameType::kClockEdge:
      stream = kEdges;
      break;
    case FrameType::kMargReading:
      stream = kMarg;
      break;
    case FrameType::kStatus:
      stream = kStatusStream;
      break;
    default:
      return false;
  }
  // Decode first so that a malformed payload changes nothing.
  std::optional<FieldPayload> field;
  std::optional<MargPayload> marg;
  std::optional<StatusPayload> status;
  if (stream == kReadings && !(field = DecodeField(frame.payload))) return false;
  if (stream == kMarg && !(marg = DecodeMarg(frame.payload))) return false;
  if (stream == kStatusStream && !(status = DecodeStatus(frame.payload))) return false;
  if (stream == kEdges && !frame.payload.empty()) return false;

  // Reset detection: an explicit boot status after other frames, or time going backwards within
  // one frame type (each type's times strictly increase between resets).
  const bool boot = status && (status->flags & kStatusBoot);
  Stream& s = streams_[stream];
  if (seen_any_ && (boot || (s.have_time && frame.mcu_time_us < s.last_time_us))) {
    OnReset();
    out->mcu_reset = true;
  }
  seen_any_ = true;
  s.have_time = true;
  s.last_time_us = frame.mcu_time_us;

  switch (stream) {
    case kReadings: {
      Sequence(stream, frame.seq, &counters_.readings_lost);
      HallSample r;
      r.epoch = epoch_;
      r.seq = frame.seq;
      r.mcu_time_us = frame.mcu_time_us;
      r.reg_x = field->reg_x;
      r.reg_y = field->reg_y;
      r.reg_z = field->reg_z;
      r.gain_sel = field->gain_sel;
      r.res_x = field->res_x;
      r.res_y = field->res_y;
      r.res_z = field->res_z;
      r.bx_uT = RegisterToMicrotesla(r.reg_x, Axis::kX, r.gain_sel, r.res_x);
      r.by_uT = RegisterToMicrotesla(r.reg_y, Axis::kY, r.gain_sel, r.res_y);
      r.bz_uT = RegisterToMicrotesla(r.reg_z, Axis::kZ, r.gain_sel, r.res_z);
      out->readings.push_back(r);
      ++counters_.readings;
      break;
    }
    case kEdges:
      Sequence(stream, frame.seq, &counters_.clock_edges_lost);
      out->edges.push_back(ClockEdge{epoch_, frame.seq, frame.mcu_time_us});
      ++counters_.clock_edges;
      break;
    case kMarg: {
      Sequence(stream, frame.seq, &counters_.marg_lost);
      MargReading m;
      m.epoch = epoch_;
      m.seq = frame.seq;
      m.mcu_time_us = frame.mcu_time_us;
      for (int i = 0; i < 3; ++i) {
        m.accel_g[i] = marg->accel_g[i];
        m.gyro_dps[i] = marg->gyro_dps[i];
        m.mag_uT[i] = marg->mag_uT[i];
      }
      out->marg.push_back(m);
      ++counters_.marg_readings;
      break;
    }
    case kStatusStream:
      Sequence(stream, frame.seq, nullptr);
      ++counters_.status_frames;
      counters_.sensor_overruns = status->sensor_overruns;
      CatchUp(kReadings, status->next_reading_seq, &counters_.readings_lost);
      CatchUp(kEdges, status->next_edge_seq, &counters_.clock_edges_lost);
      CatchUp(kMarg, status->next_marg_seq, &counters_.marg_lost);
      if (status->flags & kStatusEndOfData) out->end_of_data = true;
      break;
    default:
      break;
  }
  return true;
}

}  // namespace msmcal::hall_mcu
