#include "drivers/hall_mcu/protocol.h"

#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <string>

namespace msmcal::hall_mcu {
namespace {

TEST(Crc16, CcittFalseCheckValue) {
  const std::string check = "123456789";
  EXPECT_EQ(
      Crc16(std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(check.data()), check.size())),
      0x29B1);
  EXPECT_EQ(Crc16({}), 0xFFFF);
}

TEST(EncodeFrame, GoldenClockEdgeBytes) {
  // Transcript a firmware author can check against: clock edge, seq 3, t = 0x0102030405 us.
  const Frame f{FrameType::kClockEdge, 3, 0x0102030405, {}};
  const std::vector<uint8_t> bytes = EncodeFrame(f);
  const std::vector<uint8_t> header = {0xA5, 0x5A, 0x00, 0x02, 0x03, 0x00, 0x00, 0x00,
                                       0x05, 0x04, 0x03, 0x02, 0x01, 0x00, 0x00, 0x00};
  ASSERT_EQ(bytes.size(), 18u);
  EXPECT_EQ(std::vector<uint8_t>(bytes.begin(), bytes.begin() + 16), header);
  const uint16_t crc = Crc16(std::span<const uint8_t>(header.data() + 2, 14));
  EXPECT_EQ(bytes[16], crc & 0xFF);
  EXPECT_EQ(bytes[17], crc >> 8);
}

TEST(EncodeFrame, RejectsOversizedPayload) {
  Frame f{FrameType::kCommandReply, 0, 0, std::vector<uint8_t>(kMaxPayload + 1)};
  EXPECT_THROW(EncodeFrame(f), std::invalid_argument);
}

TEST(Mlx90393, SensitivityTableCorners) {
  EXPECT_DOUBLE_EQ(SensitivityUtPerLsb(Axis::kX, 0, 0), 0.751);
  EXPECT_DOUBLE_EQ(SensitivityUtPerLsb(Axis::kY, 0, 0), 0.751);
  EXPECT_DOUBLE_EQ(SensitivityUtPerLsb(Axis::kZ, 0, 0), 1.210);
  EXPECT_DOUBLE_EQ(SensitivityUtPerLsb(Axis::kX, 7, 0), 0.150);
  EXPECT_DOUBLE_EQ(SensitivityUtPerLsb(Axis::kZ, 7, 0), 0.242);
  EXPECT_DOUBLE_EQ(SensitivityUtPerLsb(Axis::kX, 7, 3), 1.202);
  EXPECT_DOUBLE_EQ(SensitivityUtPerLsb(Axis::kZ, 0, 3), 9.680);
  EXPECT_THROW(SensitivityUtPerLsb(Axis::kX, 8, 0), std::invalid_argument);
  EXPECT_THROW(SensitivityUtPerLsb(Axis::kX, 0, 4), std::invalid_argument);
}

TEST(Mlx90393, SensitivityDoublesWithEachResStep) {
  // The datasheet's RES columns scale by 2, up to the table's rounding to 0.001 uT (two rounded
  // entries: |s_r - 2 s_(r-1)| <= 0.0005 + 2 * 0.0005). One entry breaks the rule in the datasheet
  // itself (GAIN_SEL 1, RES 3, X/Y: 4.840, where 2 x 2.403 = 4.806); we keep the datasheet value.
  for (uint8_t g = 0; g < 8; ++g) {
    for (uint8_t r = 1; r < 4; ++r) {
      for (Axis a : {Axis::kX, Axis::kZ}) {
        if (g == 1 && r == 3 && a == Axis::kX) continue;
        EXPECT_NEAR(SensitivityUtPerLsb(a, g, r), 2 * SensitivityUtPerLsb(a, g, r - 1), 1.5e-3)
            << int(g) << " " << int(r);
      }
    }
  }
  EXPECT_DOUBLE_EQ(SensitivityUtPerLsb(Axis::kX, 1, 3), 4.840);
}

TEST(Mlx90393, SignedCountFollowsResEncoding) {
  EXPECT_EQ(SignedCount(0xFFFF, 0), -1);
  EXPECT_EQ(SignedCount(0x8000, 1), -32768);
  EXPECT_EQ(SignedCount(0x8000, 2), 0);
  EXPECT_EQ(SignedCount(0x0000, 2), -32768);
  EXPECT_EQ(SignedCount(0x4000, 3), 0);
  EXPECT_EQ(SignedCount(0x0000, 3), -16384);
  for (uint8_t res = 0; res < 4; ++res) {
    for (int32_t c : {-16384, -1000, -1, 0, 1, 777, 16383}) {
      EXPECT_EQ(SignedCount(RegisterFromCount(c, res), res), c) << int(res);
    }
  }
  EXPECT_EQ(SignedCount(RegisterFromCount(20000, 3), 3), 16383);  // clamped
}

TEST(Mlx90393, QuantisationIsExactlyInvertible) {
  // The mock quantises with MicroteslaToRegister; the host converts back. Converting the host's
  // value again must give the same register (the quantised value is a fixed point).
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> field(-3000, 3000);
  for (int i = 0; i < 2000; ++i) {
    const uint8_t g = rng() % 8, r = rng() % 4;
    const Axis a = static_cast<Axis>(rng() % 3);
    const double b = field(rng);
    const uint16_t reg = MicroteslaToRegister(b, a, g, r);
    const double host = RegisterToMicrotesla(reg, a, g, r);
    EXPECT_EQ(MicroteslaToRegister(host, a, g, r), reg);
    if (SignedCount(reg, r) > -16384 && SignedCount(reg, r) < 16383) {
      EXPECT_LE(std::abs(host - b), 0.5 * SensitivityUtPerLsb(a, g, r) + 1e-9);
    }
  }
}

TEST(Payloads, RoundTrip) {
  const FieldPayload fp{0x1234, 0xFEDC, 0x8000, 5, 0, 2, 3};
  auto f = DecodeField(EncodeField(fp));
  ASSERT_TRUE(f);
  EXPECT_EQ(f->reg_x, 0x1234);
  EXPECT_EQ(f->reg_y, 0xFEDC);
  EXPECT_EQ(f->reg_z, 0x8000);
  EXPECT_EQ(f->gain_sel, 5);
  EXPECT_EQ(f->res_z, 3);
  std::vector<uint8_t> bad = EncodeField(fp);
  bad[6] = 8;  // gain_sel out of range
  EXPECT_FALSE(DecodeField(bad));

  const StatusPayload sp{kStatusBoot | kStatusStreaming, 1000, 7, 8, 9, 10};
  auto s = DecodeStatus(EncodeStatus(sp));
  ASSERT_TRUE(s);
  EXPECT_EQ(s->flags, sp.flags);
  EXPECT_EQ(s->rate_hz, 1000);
  EXPECT_EQ(s->next_reading_seq, 7u);
  EXPECT_EQ(s->next_edge_seq, 8u);
  EXPECT_EQ(s->next_marg_seq, 9u);
  EXPECT_EQ(s->sensor_overruns, 10u);

  MargPayload mp;
  mp.accel_g = {0.1f, -0.2f, 0.98f};
  mp.gyro_dps = {1.5f, 0, -3};
  mp.mag_uT = {20, -5, -43.25f};
  auto m = DecodeMarg(EncodeMarg(mp));
  ASSERT_TRUE(m);
  EXPECT_EQ(m->accel_g, mp.accel_g);
  EXPECT_EQ(m->gyro_dps, mp.gyro_dps);
  EXPECT_EQ(m->mag_uT, mp.mag_uT);

  const IdentifyInfo id{1, 2, 3, SensorType::kMarg, "NUCLEO-F439ZI"};
  auto i = DecodeIdentify(EncodeIdentify(id));
  ASSERT_TRUE(i);
  EXPECT_EQ(i->fw_minor, 2);
  EXPECT_EQ(i->sensor_type, SensorType::kMarg);
  EXPECT_EQ(i->board, "NUCLEO-F439ZI");

  const SensorSettings ss{3, 1, 1, 2, 3, 7};
  auto d = DecodeSensorSettings(EncodeSensorSettings(ss));
  ASSERT_TRUE(d);
  EXPECT_EQ(*d, ss);
  EXPECT_EQ(DecodeRate(EncodeRate(4321)), 4321);
}

TEST(SensorSettings, ValidateNamesFieldValueAndConstraint) {
  SensorSettings s;
  EXPECT_EQ(s.Validate(), "");
  s.res_z = 4;
  EXPECT_EQ(s.Validate(), "SensorSettings.res_z = 4: violated constraint 0 <= res_z <= 3");
}

}  // namespace
}  // namespace msmcal::hall_mcu
