#include "drivers/hall_mcu/protocol.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace msmcal::hall_mcu {
namespace {

void PutU16(std::vector<uint8_t>* out, uint16_t v) {
  out->push_back(static_cast<uint8_t>(v & 0xFF));
  out->push_back(static_cast<uint8_t>(v >> 8));
}
void PutU32(std::vector<uint8_t>* out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out->push_back(static_cast<uint8_t>(v >> (8 * i)));
}
void PutU64(std::vector<uint8_t>* out, uint64_t v) {
  for (int i = 0; i < 8; ++i) out->push_back(static_cast<uint8_t>(v >> (8 * i)));
}
void PutF32(std::vector<uint8_t>* out, float f) {
  uint32_t v = 0;
  std::memcpy(&v, &f, sizeof(v));
  PutU32(out, v);
}
uint16_t GetU16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
uint32_t GetU32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}
float GetF32(const uint8_t* p) {
  const uint32_t v = GetU32(p);
  float f = 0;
  std::memcpy(&f, &v, sizeof(f));
  return f;
}

// Datasheet sensitivity table, HALLCONF = 0xC: [GAIN_SEL][RES][0: X/Y, 1: Z] in uT/LSB.
constexpr double kSensitivity[8][4][2] = {
    {{0.751, 1.210}, {1.502, 2.420}, {3.004, 4.840}, {6.009, 9.680}},
    {{0.601, 0.968}, {1.202, 1.936}, {2.403, 3.872}, {4.840, 7.744}},
    {{0.451, 0.726}, {0.901, 1.452}, {1.803, 2.904}, {3.605, 5.808}},
    {{0.376, 0.605}, {0.751, 1.210}, {1.502, 2.420}, {3.004, 4.840}},
    {{0.300, 0.484}, {0.601, 0.968}, {1.202, 1.936}, {2.403, 3.872}},
    {{0.250, 0.403}, {0.501, 0.807}, {1.001, 1.613}, {2.003, 3.227}},
    {{0.200, 0.323}, {0.401, 0.645}, {0.801, 1.291}, {1.602, 2.581}},
    {{0.150, 0.242}, {0.300, 0.484}, {0.601, 0.968}, {1.202, 1.936}},
};

}  // namespace

const char* ToString(FrameType type) {
  switch (type) {
    case FrameType::kFieldReading:
      return "field_reading";
    case FrameType::kClockEdge:
      return "clock_edge";
    case FrameType::kStatus:
      return "status";
    case FrameType::kCommandReply:
      return "command_reply";
    case FrameType::kMargReading:
      return "marg_reading";
    case FrameType::kIdentify:
      return "identify";
    case FrameType::kStartStreaming:
      return "start_streaming";
    case FrameType::kStopStreaming:
      return "stop_streaming";
    case FrameType::kSetRate:
      return "set_rate";
    case FrameType::kSetSensor:
      return "set_sensor";
    case FrameType::kGetStatus:
      return "get_status";
  }
  return "unknown";
}

std::optional<size_t> PayloadSize(uint8_t type, bool* fixed) {
  bool is_fixed = true;
  std::optional<size_t> size;
  switch (static_cast<FrameType>(type)) {
    case FrameType::kFieldReading:
      size = kFieldPayloadSize;
      break;
    case FrameType::kClockEdge:
      size = 0;
      break;
    case FrameType::kStatus:
      size = kStatusPayloadSize;
      break;
    case FrameType::kCommandReply:
      size = kMaxPayload;
      is_fixed = false;
      break;
    case FrameType::kMargReading:
      size = kMargPayloadSize;
      break;
    case FrameType::kIdentify:
    case FrameType::kStartStreaming:
    case FrameType::kStopStreaming:
    case FrameType::kGetStatus:
      size = 0;
      break;
    case FrameType::kSetRate:
      size = 2;
      break;
    case FrameType::kSetSensor:
      size = 6;
      break;
  }
  if (fixed != nullptr) *fixed = is_fixed;
  return size;
}

uint16_t Crc16(std::span<const uint8_t> bytes, uint16_t crc) {
  for (uint8_t b : bytes) {
    crc ^= static_cast<uint16_t>(b) << 8;
    for (int i = 0; i < 8; ++i) {
      crc = (crc & 0x8000) ? static_cast<uint16_t>((crc << 1) ^ 0x1021)
                           : static_cast<uint16_t>(crc << 1);
    }
  }
  return crc;
}

void EncodeFrame(const Frame& frame, std::vector<uint8_t>* out) {
  if (frame.payload.size() > kMaxPayload) {
    throw std::invalid_argument("hall_mcu::EncodeFrame: payload of " +
                                std::to_string(frame.payload.size()) + " bytes exceeds " +
                                std::to_string(kMaxPayload));
  }
  const size_t start = out->size();
  out->push_back(kSync0);
  out->push_back(kSync1);
  out->push_back(static_cast<uint8_t>(frame.payload.size()));
  out->push_back(static_cast<uint8_t>(frame.type));
  PutU32(out, frame.seq);
  PutU64(out, static_cast<uint64_t>(frame.mcu_time_us));
  out->insert(out->end(), frame.payload.begin(), frame.payload.end());
  const uint16_t crc =
      Crc16(std::span<const uint8_t>(out->data() + start + 2, out->size() - start - 2));
  PutU16(out, crc);
}

std::vector<uint8_t> EncodeFrame(const Frame& frame) {
  std::vector<uint8_t> out;
  EncodeFrame(frame, &out);
  return out;
}

std::string SensorSettings::Validate() const {
  auto bad = [](const char* field, int value, const char* constraint) {
    return std::string("SensorSettings.") + field + " = " + std::to_string(value) +
           ": violated constraint " + constraint;
  };
  if (gain_sel > 7) return bad("gain_sel", gain_sel, "0 <= gain_sel <= 7");
  if (res_x > 3) return bad("res_x", res_x, "0 <= res_x <= 3");
  if (res_y > 3) return bad("res_y", res_y, "0 <= res_y <= 3");
  if (res_z > 3) return bad("res_z", res_z, "0 <= res_z <= 3");
  if (osr > 3) return bad("osr", osr, "0 <= osr <= 3");
  if (dig_filt > 7) return bad("dig_filt", dig_filt, "0 <= dig_filt <= 7");
  return {};
}

double SensitivityUtPerLsb(Axis axis, uint8_t gain_sel, uint8_t res) {
  if (gain_sel > 7 || res > 3) {
    throw std::invalid_argument("SensitivityUtPerLsb: gain_sel " + std::to_string(gain_sel) +
                                " (0..7) or res " + std::to_string(res) + " (0..3) out of range");
  }
  return kSensitivity[gain_sel][res][axis == Axis::kZ ? 1 : 0];
}

int32_t SignedCount(uint16_t reg, uint8_t res) {
  switch (res) {
    case 2:
      return static_cast<int32_t>(reg) - 32768;
    case 3:
      return static_cast<int32_t>(reg) - 16384;
    default:
      return static_cast<int16_t>(reg);
  }
}

uint16_t RegisterFromCount(int32_t count, uint8_t res) {
  switch (res) {
    case 2:
      return static_cast<uint16_t>(std::clamp(count, -32768, 32767) + 32768);
    case 3:
      return static_cast<uint16_t>(std::clamp(count, -16384, 16383) + 16384);
    default:
      return static_cast<uint16_t>(static_cast<int16_t>(std::clamp(count, -32768, 32767)));
  }
}

double RegisterToMicrotesla(uint16_t reg, Axis axis, uint8_t gain_sel, uint8_t res) {
  return SignedCount(reg, res) * SensitivityUtPerLsb(axis, gain_sel, res);
}

uint16_t MicroteslaToRegister(double field_uT, Axis axis, uint8_t gain_sel, uint8_t res) {
  const double counts = field_uT / SensitivityUtPerLsb(axis, gain_sel, res);
  const double clamped = std::clamp(std::isfinite(counts) ? counts : 0.0, -40000.0, 40000.0);
  return RegisterFromCount(static_cast<int32_t>(std::lround(clamped)), res);
}

std::vector<uint8_t> EncodeField(const FieldPayload& p) {
  std::vector<uint8_t> out;
  PutU16(&out, p.reg_x);
  PutU16(&out, p.reg_y);
  PutU16(&out, p.reg_z);
  out.push_back(p.gain_sel);
  out.push_back(p.res_x);
  out.push_back(p.res_y);
  out.push_back(p.res_z);
  return out;
}

std::optional<FieldPayload> DecodeField(std::span<const uint8_t> b) {
  if (b.size() != kFieldPayloadSize) return std::nullopt;
  FieldPayload p;
  p.reg_x = GetU16(&b[0]);
  p.reg_y = GetU16(&b[2]);
  p.reg_z = GetU16(&b[4]);
  p.gain_sel = b[6];
  p.res_x = b[7];
  p.res_y = b[8];
  p.res_z = b[9];
  if (p.gain_sel > 7 || p.res_x > 3 || p.res_y > 3 || p.res_z > 3) return std::nullopt;
  return p;
}

std::vector<uint8_t> EncodeStatus(const StatusPayload& p) {
  std::vector<uint8_t> out;
  out.push_back(p.flags);
  out.push_back(0);
  PutU16(&out, p.rate_hz);
  PutU32(&out, p.next_reading_seq);
  PutU32(&out, p.next_edge_seq);
  PutU32(&out, p.next_marg_seq);
  PutU32(&out, p.sensor_overruns);
  return out;
}

std::optional<StatusPayload> DecodeStatus(std::span<const uint8_t> b) {
  if (b.size() != kStatusPayloadSize) return std::nullopt;
  StatusPayload p;
  p.flags = b[0];
  p.rate_hz = GetU16(&b[2]);
  p.next_reading_seq = GetU32(&b[4]);
  p.next_edge_seq = GetU32(&b[8]);
  p.next_marg_seq = GetU32(&b[12]);
  p.sensor_overruns = GetU32(&b[16]);
  return p;
}

std::vector<uint8_t> EncodeMarg(const MargPayload& p) {
  std::vector<uint8_t> out;
  for (float f : p.accel_g) PutF32(&out, f);
  for (float f : p.gyro_dps) PutF32(&out, f);
  for (float f : p.mag_uT) PutF32(&out, f);
  return out;
}

std::optional<MargPayload> DecodeMarg(std::span<const uint8_t> b) {
  if (b.size() != kMargPayloadSize) return std::nullopt;
  MargPayload p;
  for (int i = 0; i < 3; ++i) {
    p.accel_g[i] = GetF32(&b[4 * i]);
    p.gyro_dps[i] = GetF32(&b[12 + 4 * i]);
    p.mag_uT[i] = GetF32(&b[24 + 4 * i]);
  }
  return p;
}

const char* ToString(ReplyResult result) {
  switch (result) {
    case ReplyResult::kOk:
      return "ok";
    case ReplyResult::kBadLength:
      return "bad_length";
    case ReplyResult::kBadValue:
      return "bad_value";
    case ReplyResult::kUnsupported:
      return "unsupported";
    case ReplyResult::kSensorError:
      return "sensor_error";
  }
  return "unknown";
}

std::vector<uint8_t> EncodeReply(const ReplyPayload& p) {
  std::vector<uint8_t> out;
  out.push_back(p.command);
  out.push_back(static_cast<uint8_t>(p.result));
  out.insert(out.end(), p.data.begin(), p.data.end());
  return out;
}

std::optional<ReplyPayload> DecodeReply(std::span<const uint8_t> b) {
  if (b.size() < 2 || b.size() > kMaxPayload) return std::nullopt;
  ReplyPayload p;
  p.command = b[0];
  p.result = static_cast<ReplyResult>(b[1]);
  p.data.assign(b.begin() + 2, b.end());
  return p;
}

std::vector<uint8_t> EncodeIdentify(const IdentifyInfo& info) {
  const size_t n = std::min<size_t>(info.board.size(), 40);
  std::vector<uint8_t> out;
  out.reserve(4 + n);
  out.push_back(info.fw_major);
  out.push_back(info.fw_minor);
  out.push_back(info.fw_patch);
  out.push_back(static_cast<uint8_t>(info.sensor_type));
  for (size_t i = 0; i < n; ++i) out.push_back(static_cast<uint8_t>(info.board[i]));
  return out;
}

std::optional<IdentifyInfo> DecodeIdentify(std::span<const uint8_t> b) {
  if (b.size() < 4 || b.size() > 44) return std::nullopt;
  IdentifyInfo info;
  info.fw_major = b[0];
  info.fw_minor = b[1];
  info.fw_patch = b[2];
  info.sensor_type = static_cast<SensorType>(b[3]);
  info.board.assign(b.begin() + 4, b.end());
  return info;
}

std::vector<uint8_t> EncodeRate(uint16_t rate_hz) {
  std::vector<uint8_t> out;
  PutU16(&out, rate_hz);
  return out;
}

std::optional<uint16_t> DecodeRate(std::span<const uint8_t> b) {
  if (b.size() != 2) return std::nullopt;
  return GetU16(b.data());
}

std::vector<uint8_t> EncodeSensorSettings(const SensorSettings& s) {
  return {s.gain_sel, s.res_x, s.res_y, s.res_z, s.osr, s.dig_filt};
}

std::optional<SensorSettings> DecodeSensorSettings(std::span<const uint8_t> b) {
  if (b.size() != 6) return std::nullopt;
  SensorSettings s{b[0], b[1], b[2], b[3], b[4], b[5]};
  if (!s.Validate().empty()) return std::nullopt;
  return s;
}

}  // namespace msmcal::hall_mcu
