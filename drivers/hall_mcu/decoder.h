#pragma once
// Streaming frame decoder and stream tracker for the Hall MCU protocol. Pure: bytes in, frames and
// value types out; no I/O. Fuzzed by scripts/fuzz-hall-decoder.

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "drivers/hall_mcu/hall_sensor.h"
#include "drivers/hall_mcu/protocol.h"

namespace msmcal::hall_mcu {

struct DecoderCounters {
  uint64_t frames = 0;
  uint64_t crc_errors = 0;
  uint64_t bad_headers = 0;
  uint64_t bytes_discarded = 0;
};

// Finds frames in an arbitrary byte stream. After garbage, a bad CRC or an impossible header it
// skips one byte and searches for the next sync word, so a damaged frame never hides the frame
// after it. Memory is bounded (at most one frame plus the last Feed() is buffered) and every
// Next() call either returns a frame, discards at least one byte, or reports that it needs more.
class FrameDecoder {
 public:
  void Feed(std::span<const uint8_t> bytes);
  // The next complete, CRC-valid frame, or nullopt when more bytes are needed.
  std::optional<Frame> Next();
  const DecoderCounters& counters() const { return counters_; }
  size_t buffered() const { return buf_.size() - head_; }

 private:
  void Discard(size_t n);
  std::vector<uint8_t> buf_;
  size_t head_ = 0;
  DecoderCounters counters_;
};

// Turns MCU->host data frames into value types and keeps the loss/reset accounting
// (docs/protocols/hall-mcu.md, "Sequence numbers, losses and resets").
class StreamTracker {
 public:
  // Handles kFieldReading, kClockEdge, kMargReading and kStatus frames; appends readings to *out
  // and updates counters(). Other frame types and malformed payloads are ignored (returns false).
  bool Accept(const Frame& frame, HallBatch* out);

  // Counters of the tracker only (decoder and stall fields are left at 0).
  const HallCounters& counters() const { return counters_; }
  uint32_t epoch() const { return epoch_; }

 private:
  struct Stream {
    bool seq_known = false;
    uint32_t expected_seq = 0;
    bool have_time = false;
    int64_t last_time_us = 0;
  };
  enum { kReadings = 0, kEdges = 1, kMarg = 2, kStatusStream = 3, kNumStreams = 4 };
  void OnReset();
  // Returns false if the frame's time went backwards (=> reset handled by the caller).
  void Sequence(int stream, uint32_t seq, uint64_t* lost);
  void CatchUp(int stream, uint32_t next_seq, uint64_t* lost);

  Stream streams_[kNumStreams];
  bool seen_any_ = false;
  uint32_t epoch_ = 0;
  HallCounters counters_;
};

}  // namespace msmcal::hall_mcu
