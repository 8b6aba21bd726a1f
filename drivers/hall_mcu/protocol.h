#pragma once
// Hall MCU serial protocol (docs/protocols/hall-mcu.md): frame layout, CRC, payload codecs and the
// MLX90393 count -> microtesla conversion. Pure functions over bytes: no I/O, no clocks, no
// threads. Shared by the driver (host side) and the mock MCU (firmware side).
//
// Frame (all multi-byte fields little-endian):
//   off size field
//   0   2    sync 0xA5 0x5A
//   2   1    payload length N (bytes)
//   3   1    type (FrameType)
//   4   4    seq (uint32, per-type counter; see the protocol document)
//   8   8    mcu_time_us (int64, MCU microsecond counter, starts at 0 on boot)
//   16  N    payload
//   16+N 2   CRC-16/CCITT-FALSE over bytes 2 .. 16+N-1 (length, type, seq, time, payload)

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace msmcal::hall_mcu {

inline constexpr uint8_t kSync0 = 0xA5;
inline constexpr uint8_t kSync1 = 0x5A;
inline constexpr size_t kHeaderSize = 16;
inline constexpr size_t kCrcSize = 2;
inline constexpr size_t kMaxPayload = 64;
inline constexpr size_t kMaxFrameSize = kHeaderSize + kMaxPayload + kCrcSize;

enum class FrameType : uint8_t {
  // MCU -> host.
  kFieldReading = 0x01,
  kClockEdge = 0x02,
  kStatus = 0x03,
  kCommandReply = 0x04,
  kMargReading = 0x05,
  // Host -> MCU.
  kIdentify = 0x81,
  kStartStreaming = 0x82,
  kStopStreaming = 0x83,
  kSetRate = 0x84,
  kSetSensor = 0x85,
  kGetStatus = 0x86,
};

const char* ToString(FrameType type);

// Payload size of each type; variable-size types return their maximum and set *fixed=false.
// Returns nullopt for an unknown type byte.
std::optional<size_t> PayloadSize(uint8_t type, bool* fixed);

struct Frame {
  FrameType type = FrameType::kStatus;
  uint32_t seq = 0;
  int64_t mcu_time_us = 0;
  std::vector<uint8_t> payload;
};

// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final xor
// (check value for "123456789" is 0x29B1).
uint16_t Crc16(std::span<const uint8_t> bytes, uint16_t crc = 0xFFFF);

// Appends the encoded frame to *out. Throws std::invalid_argument if the payload is longer than
// kMaxPayload.
void EncodeFrame(const Frame& frame, std::vector<uint8_t>* out);
std::vector<uint8_t> EncodeFrame(const Frame& frame);

// ---------------------------------------------------------------------------------------------
// MLX90393 settings and conversion (datasheet rev. 008, table "sensitivity", HALLCONF = 0xC).

struct SensorSettings {
  uint8_t gain_sel = 7;  // GAIN_SEL 0..7 (0: 5x gain, 0.751/1.210 uT/LSB at RES 0; 7: 1x)
  uint8_t res_x = 0;     // RES_X 0..3
  uint8_t res_y = 0;     // RES_Y 0..3
  uint8_t res_z = 0;     // RES_Z 0..3
  uint8_t osr = 0;       // OSR 0..3 (magnetic oversampling)
  uint8_t dig_filt = 0;  // DIG_FILT 0..7

  // Empty when valid; else names the field, its value and the constraint.
  std::string Validate() const;
  bool operator==(const SensorSettings&) const = default;
};

enum class Axis { kX = 0, kY = 1, kZ = 2 };

// Sensitivity in uT/LSB for the axis (X and Y share a column) at GAIN_SEL and RES (HALLCONF 0xC).
// Requires gain_sel <= 7, res <= 3 (throws std::invalid_argument otherwise).
double SensitivityUtPerLsb(Axis axis, uint8_t gain_sel, uint8_t res);

// Signed count from the 16-bit output register, as the datasheet specifies per RES:
// RES 0,1: two's complement; RES 2: register - 32768; RES 3: register - 16384.
int32_t SignedCount(uint16_t reg, uint8_t res);
// Inverse of SignedCount; clamps to the representable range of that RES
// (RES 0,1: [-32768, 32767]; RES 2: [-32768, 32767]; RES 3: [-16384, 16383]).
uint16_t RegisterFromCount(int32_t count, uint8_t res);

// Field in uT = SignedCount(reg, res) * SensitivityUtPerLsb(axis, gain_sel, res).
double RegisterToMicrotesla(uint16_t reg, Axis axis, uint8_t gain_sel, uint8_t res);
// Nearest register value for a field (used by the mock MCU); RegisterToMicrotesla of the result
// is the quantised field the host will see.
uint16_t MicroteslaToRegister(double field_uT, Axis axis, uint8_t gain_sel, uint8_t res);

// ---------------------------------------------------------------------------------------------
// Payloads.

// kFieldReading, 10 bytes: reg_x u16, reg_y u16, reg_z u16, gain_sel u8, res_x u8, res_y u8,
// res_z u8.
struct FieldPayload {
  uint16_t reg_x = 0, reg_y = 0, reg_z = 0;
  uint8_t gain_sel = 0, res_x = 0, res_y = 0, res_z = 0;
};
inline constexpr size_t kFieldPayloadSize = 10;
std::vector<uint8_t> EncodeField(const FieldPayload& p);
std::optional<FieldPayload> DecodeField(std::span<const uint8_t> payload);

// kClockEdge: empty payload (the edge time is the header's mcu_time_us).

// kStatus, 20 bytes: flags u8, reserved u8, rate_hz u16, next_reading_seq u32, next_edge_seq u32,
// next_marg_seq u32, sensor_overruns u32.
inline constexpr uint8_t kStatusBoot = 0x01;         // first status frame after power-up/reset
inline constexpr uint8_t kStatusStreaming = 0x02;    // streaming is on
inline constexpr uint8_t kStatusSensorError = 0x04;  // the sensor did not answer
inline constexpr uint8_t kStatusEndOfData = 0x08;    // replay/simulation source exhausted (mock)
struct StatusPayload {
  uint8_t flags = 0;
  uint16_t rate_hz = 0;
  uint32_t next_reading_seq = 0;
  uint32_t next_edge_seq = 0;
  uint32_t next_marg_seq = 0;
  uint32_t sensor_overruns = 0;
};
inline constexpr size_t kStatusPayloadSize = 20;
std::vector<uint8_t> EncodeStatus(const StatusPayload& p);
std::optional<StatusPayload> DecodeStatus(std::span<const uint8_t> payload);

// kMargReading, 36 bytes: 9 x float32 (IEEE 754, LE): accel x y z [g], gyro x y z [deg/s],
// mag x y z [uT], all in the board's sensor frame.
struct MargPayload {
  std::array<float, 3> accel_g{};
  std::array<float, 3> gyro_dps{};
  std::array<float, 3> mag_uT{};
};
inline constexpr size_t kMargPayloadSize = 36;
std::vector<uint8_t> EncodeMarg(const MargPayload& p);
std::optional<MargPayload> DecodeMarg(std::span<const uint8_t> payload);

// kCommandReply, 2 + k bytes: command type u8, result u8, then command-specific data.
enum class ReplyResult : uint8_t {
  kOk = 0,
  kBadLength = 1,
  kBadValue = 2,
  kUnsupported = 3,
  kSensorError = 4,
};
const char* ToString(ReplyResult result);
struct ReplyPayload {
  uint8_t command = 0;
  ReplyResult result = ReplyResult::kOk;
  std::vector<uint8_t> data;
};
std::vector<uint8_t> EncodeReply(const ReplyPayload& p);
std::optional<ReplyPayload> DecodeReply(std::span<const uint8_t> payload);

// Identify reply data: fw_major u8, fw_minor u8, fw_patch u8, sensor_type u8, then an ASCII
// board name (0..40 bytes, not terminated).
enum class SensorType : uint8_t { kMlx90393 = 1, kMarg = 2 };
struct IdentifyInfo {
  uint8_t fw_major = 0, fw_minor = 0, fw_patch = 0;
  SensorType sensor_type = SensorType::kMlx90393;
  std::string board;
};
std::vector<uint8_t> EncodeIdentify(const IdentifyInfo& info);
std::optional<IdentifyInfo> DecodeIdentify(std::span<const uint8_t> data);

// kSetRate command payload: rate_hz u16 (1..5000). kSetSensor payload: gain_sel, res_x, res_y,
// res_z, osr, dig_filt (6 x u8).
std::vector<uint8_t> EncodeRate(uint16_t rate_hz);
std::optional<uint16_t> DecodeRate(std::span<const uint8_t> payload);
std::vector<uint8_t> EncodeSensorSettings(const SensorSettings& s);
std::optional<SensorSettings> DecodeSensorSettings(std::span<const uint8_t> payload);

}  // namespace msmcal::hall_mcu
