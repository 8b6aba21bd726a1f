// libFuzzer target for the Hall MCU frame decoder and stream tracker. Built by fuzz/CMakeLists.txt
// (-DMSMCAL_FUZZ=ON, clang) and run by scripts/fuzz; seeds in fuzz/corpus/hall_decoder/.
//
// Input: byte 0 picks the chunk size the stream is fed in (1..64), the rest is the byte stream.
// Checks: no crash / over-read (sanitizers), termination (every Next() consumes or stops), bounded
// buffering, every decoded frame re-encodes to a CRC-valid frame of legal length, and the
// tracker's counters never exceed what was decoded.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "drivers/hall_mcu/decoder.h"

using namespace msmcal::hall_mcu;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const size_t chunk = 1 + data[0] % 64;
  FrameDecoder decoder;
  StreamTracker tracker;
  HallBatch batch;
  uint64_t frames = 0;
  for (size_t off = 1; off < size; off += chunk) {
    const size_t n = std::min(chunk, size - off);
    decoder.Feed(std::span<const uint8_t>(data + off, n));
    size_t guard = 0;
    while (auto frame = decoder.Next()) {
      ++frames;
      if (frame->payload.size() > kMaxPayload) std::abort();
      const std::vector<uint8_t> bytes = EncodeFrame(*frame);
      if (Crc16(std::span<const uint8_t>(bytes.data() + 2, bytes.size() - 4)) !=
          static_cast<uint16_t>(bytes[bytes.size() - 2] | (bytes[bytes.size() - 1] << 8))) {
        std::abort();
      }
      tracker.Accept(*frame, &batch);
      if (++guard > size) std::abort();  // more frames than bytes: a loop
    }
    if (decoder.buffered() > kMaxFrameSize + chunk) std::abort();
  }
  const HallCounters& c = tracker.counters();
  if (c.readings + c.clock_edges + c.marg_readings + c.status_frames > frames) std::abort();
  if (batch.readings.size() != c.readings) std::abort();
  if (decoder.counters().frames != frames) std::abort();
  return 0;
}
