#pragma once
// VXI-11 (TCP/IP Instrument Protocol, VXIbus Consortium, rev. 1.0) as pure functions over bytes:
// XDR (RFC 4506) encoding, ONC RPC v2 call/reply messages (RFC 5531) with TCP record marking,
// the portmapper's GETPORT (RFC 1833, version 2), and the argument/result structs of the VXI-11
// core and abort channels. No I/O: the server (vxi11_server.h) puts these bytes on sockets.
//
// Decoding failures throw Vxi11DecodeError (a std::runtime_error naming what was short or
// malformed); encoders never fail.

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace msmcal::sim::vxi11 {

// Program numbers and versions.
inline constexpr uint32_t kPortmapperProgram = 100000;  // PMAP_PROG, version 2
inline constexpr uint32_t kPortmapperVersion = 2;
inline constexpr uint32_t kCoreProgram = 0x0607AF;   // DEVICE_CORE, version 1
inline constexpr uint32_t kAbortProgram = 0x0607B0;  // DEVICE_ASYNC, version 1
inline constexpr uint32_t kIntrProgram = 0x0607B1;   // DEVICE_INTR (client side)
inline constexpr uint32_t kVxi11Version = 1;
inline constexpr uint32_t kIpProtoTcp = 6;
inline constexpr uint32_t kIpProtoUdp = 17;

// Portmapper procedures.
inline constexpr uint32_t kPmapProcNull = 0;
inline constexpr uint32_t kPmapProcGetPort = 3;

// Core channel procedures (VXI-11 B.6), abort channel procedure.
enum CoreProc : uint32_t {
  kProcNull = 0,
  kDeviceAbort = 1,  // abort channel
  kCreateLink = 10,
  kDeviceWrite = 11,
  kDeviceRead = 12,
  kDeviceReadStb = 13,
  kDeviceTrigger = 14,
  kDeviceClear = 15,
  kDeviceRemote = 16,
  kDeviceLocal = 17,
  kDeviceLock = 18,
  kDeviceUnlock = 19,
  kDeviceEnableSrq = 20,
  kDeviceDocmd = 22,
  kDestroyLink = 23,
  kCreateIntrChan = 25,
  kDestroyIntrChan = 26,
};

// Device_ErrorCode (VXI-11 B.5.2).
enum ErrorCode : int32_t {
  kNoError = 0,
  kSyntaxError = 1,
  kDeviceNotAccessible = 3,
  kInvalidLinkId = 4,
  kParameterError = 5,
  kChannelNotEstablished = 6,
  kOperationNotSupported = 8,
  kOutOfResources = 9,
  kDeviceLocked = 11,
  kNoLockHeld = 12,
  kIoTimeout = 15,
  kIoError = 17,
  kInvalidAddress = 21,
  kAbort = 23,
  kChannelAlreadyEstablished = 29,
};

// Device_Flags bits and device_read reason bits.
inline constexpr int32_t kFlagWaitLock = 0x01;
inline constexpr int32_t kFlagEnd = 0x08;
inline constexpr int32_t kFlagTermCharSet = 0x80;
inline constexpr int32_t kReasonRequestCount = 0x01;
inline constexpr int32_t kReasonTermChar = 0x02;
inline constexpr int32_t kReasonEnd = 0x04;

class Vxi11DecodeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// XDR: big-endian 4-byte units; opaque/string data padded with zeros to a multiple of 4.
class XdrWriter {
 public:
  void PutUint(uint32_t v);
  void PutInt(int32_t v) { PutUint(static_cast<uint32_t>(v)); }
  void PutBool(bool v) { PutUint(v ? 1 : 0); }
  void PutOpaque(std::string_view bytes);  // variable-length: length, bytes, padding
  const std::string& bytes() const { return out_; }
  std::string Take() { return std::move(out_); }

 private:
  std::string out_;
};

class XdrReader {
 public:
  explicit XdrReader(std::string_view bytes) : in_(bytes) {}
  uint32_t GetUint();
  int32_t GetInt() { return static_cast<int32_t>(GetUint()); }
  bool GetBool();  // 0 or 1, else Vxi11DecodeError
  // Variable-length opaque of at most max_length bytes (padding must be present).
  std::string GetOpaque(uint32_t max_length);
  std::string_view Rest() const { return in_.substr(pos_); }
  size_t remaining() const { return in_.size() - pos_; }

 private:
  std::string_view in_;
  size_t pos_ = 0;
};

// TCP record marking (RFC 5531 section 11): each fragment has a 4-byte big-endian header, bit 31
// set on the last fragment of a record, bits 0-30 the fragment length.
std::string RecordMark(std::string_view record);  // one fragment, marked last

// Reassembles records from a byte stream fed in arbitrary chunks. Records over max_record_bytes
// make Feed() throw Vxi11DecodeError (the stream cannot be resynchronised: close it).
class RecordAssembler {
 public:
  explicit RecordAssembler(size_t max_record_bytes) : max_(max_record_bytes) {}
  void Feed(std::string_view bytes);
  // The next complete record, if any.
  std::optional<std::string> Next();
  size_t buffered() const { return pending_.size() + record_.size(); }

 private:
  size_t max_;
  std::string pending_;  // bytes not yet consumed into record_
  std::string record_;   // fragments of the record being assembled
  std::vector<std::string> done_;
  size_t next_done_ = 0;
};

// An RPC call message (msg_type CALL, rpcvers 2). Credentials and verifier are skipped (any
// flavour is accepted: the instrument does not authenticate).
struct RpcCall {
  uint32_t xid = 0;
  uint32_t rpc_version = 2;
  uint32_t program = 0;
  uint32_t version = 0;
  uint32_t procedure = 0;
  std::string args;  // the procedure's XDR arguments
};

// Decodes a call. Throws Vxi11DecodeError when the record is too short for a call header,
// is not a CALL, or its authentication fields are malformed. When `xid` is not null it is set as
// soon as the first 4 bytes are read (so a garbage call can still be answered).
RpcCall DecodeRpcCall(std::string_view record, std::optional<uint32_t>* xid = nullptr);
std::string EncodeRpcCall(const RpcCall& call);  // AUTH_NONE credentials and verifier

// accept_stat of an accepted reply.
enum AcceptStat : uint32_t {
  kSuccess = 0,
  kProgUnavail = 1,
  kProgMismatch = 2,
  kProcUnavail = 3,
  kGarbageArgs = 4,
  kSystemErr = 5,
};

// Reply records (not record-marked), AUTH_NONE verifier.
std::string EncodeAcceptedReply(uint32_t xid, AcceptStat stat, std::string_view results = {});
std::string EncodeProgMismatchReply(uint32_t xid, uint32_t low, uint32_t high);
std::string EncodeRpcMismatchReply(uint32_t xid);  // MSG_DENIED, RPC_MISMATCH 2..2

struct RpcReply {
  uint32_t xid = 0;
  bool accepted = false;  // MSG_ACCEPTED
  uint32_t stat = 0;      // accept_stat, or reject_stat when !accepted
  std::string results;    // after the accept_stat (SUCCESS results, or the mismatch range)
};
RpcReply DecodeRpcReply(std::string_view record);

// Portmapper mapping (GETPORT argument).
struct PortMapping {
  uint32_t program = 0, version = 0, protocol = 0, port = 0;
};
PortMapping DecodePortMapping(std::string_view args);
std::string EncodePortMapping(const PortMapping& m);

// ---- VXI-11 core channel structs ----
struct CreateLinkParms {
  int32_t client_id = 0;
  bool lock_device = false;
  uint32_t lock_timeout_ms = 0;
  std::string device;  // "inst0"
};
struct CreateLinkResp {
  int32_t error = 0;
  int32_t link_id = 0;
  uint32_t abort_port = 0;
  uint32_t max_recv_size = 0;
};
struct DeviceWriteParms {
  int32_t link_id = 0;
  uint32_t io_timeout_ms = 0;
  uint32_t lock_timeout_ms = 0;
  int32_t flags = 0;
  std::string data;
};
struct DeviceWriteResp {
  int32_t error = 0;
  uint32_t size = 0;
};
struct DeviceReadParms {
  int32_t link_id = 0;
  uint32_t request_size = 0;
  uint32_t io_timeout_ms = 0;
  uint32_t lock_timeout_ms = 0;
  int32_t flags = 0;
  int32_t term_char = 0;
};
struct DeviceReadResp {
  int32_t error = 0;
  int32_t reason = 0;
  std::string data;
};
// device_readstb, device_trigger, device_clear, device_remote, device_local.
struct DeviceGenericParms {
  int32_t link_id = 0;
  int32_t flags = 0;
  uint32_t lock_timeout_ms = 0;
  uint32_t io_timeout_ms = 0;
};
struct DeviceReadStbResp {
  int32_t error = 0;
  uint32_t stb = 0;  // low 8 bits
};
struct DeviceLockParms {
  int32_t link_id = 0;
  int32_t flags = 0;
  uint32_t lock_timeout_ms = 0;
};
struct DeviceEnableSrqParms {
  int32_t link_id = 0;
  bool enable = false;
  std::string handle;  // at most 40 bytes
};
struct DeviceRemoteFunc {
  uint32_t host_addr = 0, host_port = 0, prog_num = 0, prog_vers = 0;
  int32_t prog_family = 0;
};

// Bounds on decoded opaque data: a write's data up to kMaxWriteBytes (the max_recv_size the
// server announces), a device name up to 256 bytes.
inline constexpr uint32_t kMaxWriteBytes = 1u << 20;

CreateLinkParms DecodeCreateLinkParms(std::string_view args);
DeviceWriteParms DecodeDeviceWriteParms(std::string_view args);
DeviceReadParms DecodeDeviceReadParms(std::string_view args);
DeviceGenericParms DecodeDeviceGenericParms(std::string_view args);
DeviceLockParms DecodeDeviceLockParms(std::string_view args);
DeviceEnableSrqParms DecodeDeviceEnableSrqParms(std::string_view args);
DeviceRemoteFunc DecodeDeviceRemoteFunc(std::string_view args);
int32_t DecodeDeviceLink(std::string_view args);  // destroy_link, device_unlock, device_abort

std::string EncodeCreateLinkParms(const CreateLinkParms& p);
std::string EncodeDeviceWriteParms(const DeviceWriteParms& p);
std::string EncodeDeviceReadParms(const DeviceReadParms& p);
std::string EncodeDeviceGenericParms(const DeviceGenericParms& p);
std::string EncodeDeviceLockParms(const DeviceLockParms& p);
std::string EncodeDeviceLink(int32_t link_id);

std::string EncodeCreateLinkResp(const CreateLinkResp& r);
std::string EncodeDeviceWriteResp(const DeviceWriteResp& r);
std::string EncodeDeviceReadResp(const DeviceReadResp& r);
std::string EncodeDeviceReadStbResp(const DeviceReadStbResp& r);
std::string EncodeDeviceError(int32_t error);

CreateLinkResp DecodeCreateLinkResp(std::string_view results);
DeviceWriteResp DecodeDeviceWriteResp(std::string_view results);
DeviceReadResp DecodeDeviceReadResp(std::string_view results);
DeviceReadStbResp DecodeDeviceReadStbResp(std::string_view results);
int32_t DecodeDeviceError(std::string_view results);

}  // namespace msmcal::sim::vxi11
