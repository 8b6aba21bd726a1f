#include "drivers/hall_mcu/decoder.h"

#include <gtest/gtest.h>

#include <random>

namespace msmcal::hall_mcu {
namespace {

Frame Reading(uint32_t seq, int64_t t_us, uint16_t x = 100) {
  return Frame{FrameType::kFieldReading, seq, t_us, EncodeField({x, 2, 3, 7, 0, 0, 0})};
}
Frame Edge(uint32_t seq, int64_t t_us) { return Frame{FrameType::kClockEdge, seq, t_us, {}}; }
Frame Status(uint32_t seq, int64_t t_us, StatusPayload p) {
  return Frame{FrameType::kStatus, seq, t_us, EncodeStatus(p)};
}

std::vector<Frame> DecodeAll(FrameDecoder& d, const std::vector<uint8_t>& bytes) {
  d.Feed(bytes);
  std::vector<Frame> out;
  while (auto f = d.Next()) out.push_back(*f);
  return out;
}

TEST(FrameDecoder, DecodesBackToBackFramesFedOneByteAtATime) {
  std::vector<uint8_t> bytes;
  for (uint32_t i = 0; i < 50; ++i)
    EncodeFrame(Reading(i, 1000 * i, static_cast<uint16_t>(i)), &bytes);
  FrameDecoder d;
  std::vector<Frame> out;
  for (uint8_t b : bytes) {
    d.Feed(std::span<const uint8_t>(&b, 1));
    while (auto f = d.Next()) out.push_back(*f);
  }
  ASSERT_EQ(out.size(), 50u);
  for (uint32_t i = 0; i < 50; ++i) {
    EXPECT_EQ(out[i].seq, i);
    EXPECT_EQ(out[i].mcu_time_us, 1000 * i);
  }
  EXPECT_EQ(d.counters().bytes_discarded, 0u);
  EXPECT_EQ(d.buffered(), 0u);
}

TEST(FrameDecoder, ResynchronisesAfterGarbageAndCountsIt) {
  std::vector<uint8_t> bytes = {0x00, 0xA5, 0x11, 0xA5, 0xA5, 0x5A, 0x77, 0x99};
  const size_t garbage = bytes.size();
  EncodeFrame(Reading(0, 0), &bytes);
  FrameDecoder d;
  auto out = DecodeAll(d, bytes);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(d.counters().bytes_discarded, garbage);
  EXPECT_EQ(d.counters().bad_headers, 1u);  // A5 5A 77 99: unknown type 0x99
}

TEST(FrameDecoder, BadCrcLosesOnlyThatFrame) {
  std::vector<uint8_t> a = EncodeFrame(Reading(0, 0));
  std::vector<uint8_t> b = EncodeFrame(Reading(1, 1000));
  std::vector<uint8_t> c = EncodeFrame(Reading(2, 2000));
  b[20] ^= 0x10;  // payload bit
  std::vector<uint8_t> bytes = a;
  bytes.insert(bytes.end(), b.begin(), b.end());
  bytes.insert(bytes.end(), c.begin(), c.end());
  FrameDecoder d;
  auto out = DecodeAll(d, bytes);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].seq, 0u);
  EXPECT_EQ(out[1].seq, 2u);
  EXPECT_EQ(d.counters().crc_errors, 1u);
  EXPECT_EQ(d.counters().bytes_discarded, b.size());
}

TEST(FrameDecoder, EverySingleBitFlipLosesExactlyOneFrame) {
  const std::vector<uint8_t> a = EncodeFrame(Reading(0, 0));
  const std::vector<uint8_t> b = EncodeFrame(Reading(1, 1000));
  const std::vector<uint8_t> c = EncodeFrame(Edge(0, 1500));
  for (size_t bit = 0; bit < b.size() * 8; ++bit) {
    std::vector<uint8_t> bytes = a;
    std::vector<uint8_t> bad = b;
    bad[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
    bytes.insert(bytes.end(), bad.begin(), bad.end());
    bytes.insert(bytes.end(), c.begin(), c.end());
    FrameDecoder d;
    auto out = DecodeAll(d, bytes);
    ASSERT_EQ(out.size(), 2u) << "bit " << bit;
    EXPECT_EQ(out[0].seq, 0u);
    EXPECT_EQ(out[1].type, FrameType::kClockEdge);
  }
}

TEST(FrameDecoder, EveryDroppedByteLosesExactlyOneFrame) {
  const std::vector<uint8_t> a = EncodeFrame(Reading(0, 0));
  const std::vector<uint8_t> b = EncodeFrame(Reading(1, 1000));
  const std::vector<uint8_t> c = EncodeFrame(Reading(2, 2000));
  for (size_t i = 0; i < b.size(); ++i) {
    std::vector<uint8_t> bytes = a;
    std::vector<uint8_t> bad = b;
    bad.erase(bad.begin() + static_cast<long>(i));
    bytes.insert(bytes.end(), bad.begin(), bad.end());
    bytes.insert(bytes.end(), c.begin(), c.end());
    FrameDecoder d;
    auto out = DecodeAll(d, bytes);
    ASSERT_EQ(out.size(), 2u) << "dropped byte " << i;
    EXPECT_EQ(out[1].seq, 2u);
  }
}

TEST(FrameDecoder, RandomBytesNeverYieldFramesAndMemoryStaysBounded) {
  std::mt19937_64 rng(11);
  FrameDecoder d;
  size_t frames = 0;
  for (int chunk = 0; chunk < 2000; ++chunk) {
    std::vector<uint8_t> bytes(256);
    for (auto& b : bytes) b = static_cast<uint8_t>(rng());
    d.Feed(bytes);
    while (d.Next()) ++frames;
    EXPECT_LE(d.buffered(), kMaxFrameSize);
  }
  EXPECT_LE(frames, 1u);  // a random CRC match is possible (2^-16 per candidate), not expected
}

TEST(StreamTracker, CountsSequenceGapsPerType) {
  StreamTracker t;
  HallBatch b;
  for (uint32_t s : {0u, 1u, 2u, 5u, 6u, 10u}) t.Accept(Reading(s, 1000 * s), &b);
  for (uint32_t s : {0u, 2u}) t.Accept(Edge(s, 500 + 1000 * s), &b);
  EXPECT_EQ(b.readings.size(), 6u);
  EXPECT_EQ(t.counters().readings_lost, 2u + 3u);
  EXPECT_EQ(t.counters().clock_edges_lost, 1u);
  EXPECT_EQ(t.counters().resets, 0u);
  EXPECT_DOUBLE_EQ(b.readings[0].bx_uT, 100 * 0.150);
}

TEST(StreamTracker, FirstFrameSetsTheBaselineWithoutLoss) {
  StreamTracker t;
  HallBatch b;
  t.Accept(Reading(12345, 99), &b);
  t.Accept(Reading(12346, 100), &b);
  EXPECT_EQ(t.counters().readings_lost, 0u);
}

TEST(StreamTracker, StatusRevealsTailLoss) {
  StreamTracker t;
  HallBatch b;
  t.Accept(Reading(0, 0), &b);
  t.Accept(Reading(1, 1000), &b);
  StatusPayload s;
  s.next_reading_seq = 5;  // readings 2, 3, 4 were sent and lost
  s.next_edge_seq = 0;
  s.flags = kStatusEndOfData;
  t.Accept(Status(0, 5000, s), &b);
  EXPECT_EQ(t.counters().readings_lost, 3u);
  EXPECT_TRUE(b.end_of_data);
  t.Accept(Reading(5, 6000), &b);
  EXPECT_EQ(t.counters().readings_lost, 3u);
}

TEST(StreamTracker, DetectsResetByBootStatusAndByTimeGoingBack) {
  StreamTracker t;
  HallBatch b;
  StatusPayload boot;
  boot.flags = kStatusBoot;
  t.Accept(Status(0, 0, boot), &b);  // first frame: power-up, not a reset
  t.Accept(Reading(0, 10), &b);
  t.Accept(Reading(1, 1010), &b);
  t.Accept(Status(0, 0, boot), &b);  // reset
  EXPECT_EQ(t.counters().resets, 1u);
  t.Accept(Reading(0, 5), &b);  // new epoch, seq restarts at 0: no loss
  EXPECT_EQ(t.counters().readings_lost, 0u);
  EXPECT_EQ(b.readings.back().epoch, 1u);
  // Boot status lost: the time going backwards reveals the reset.
  t.Accept(Reading(1, 1005), &b);
  t.Accept(Reading(1, 3), &b);  // seq 1 after reset: reading 0 of epoch 2 was lost
  EXPECT_EQ(t.counters().resets, 2u);
  EXPECT_EQ(t.counters().readings_lost, 1u);
  EXPECT_EQ(b.readings.back().epoch, 2u);
}

TEST(StreamTracker, IgnoresMalformedPayloads) {
  StreamTracker t;
  HallBatch b;
  Frame f = Reading(0, 0);
  f.payload.pop_back();
  EXPECT_FALSE(t.Accept(f, &b));
  EXPECT_TRUE(b.empty());
}

}  // namespace
}  // namespace msmcal::hall_mcu
