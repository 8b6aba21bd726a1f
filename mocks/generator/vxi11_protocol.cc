#include "mocks/generator/vxi11_protocol.h"

namespace msmcal::sim::vxi11 {

namespace {

constexpr uint32_t kMsgCall = 0;
constexpr uint32_t kMsgReply = 1;
constexpr uint32_t kMsgAccepted = 0;
constexpr uint32_t kMsgDenied = 1;
constexpr uint32_t kRpcMismatch = 0;
constexpr uint32_t kMaxAuthBytes = 400;  // RFC 5531: opaque_auth body<400>

uint32_t Padding(size_t n) { return static_cast<uint32_t>((4 - n % 4) % 4); }

void PutNullAuth(XdrWriter& w) {
  w.PutUint(0);  // AUTH_NONE
  w.PutUint(0);  // empty body
}

void SkipAuth(XdrReader& r, const char* what) {
  r.GetUint();  // flavour: any
  try {
    r.GetOpaque(kMaxAuthBytes);
  } catch (const Vxi11DecodeError& e) {
    throw Vxi11DecodeError(std::string("RPC call: ") + what + ": " + e.what());
  }
}

std::string ReplyHeader(uint32_t xid, uint32_t reply_stat) {
  XdrWriter w;
  w.PutUint(xid);
  w.PutUint(kMsgReply);
  w.PutUint(reply_stat);
  return w.Take();
}

}  // namespace

void XdrWriter::PutUint(uint32_t v) {
  const char b[4] = {static_cast<char>(v >> 24), static_cast<char>(v >> 16),
                     static_cast<char>(v >> 8), static_cast<char>(v)};
  out_.append(b, 4);
}

void XdrWriter::PutOpaque(std::string_view bytes) {
  PutUint(static_cast<uint32_t>(bytes.size()));
  out_.append(bytes);
  out_.append(Padding(bytes.size()), '\0');
}

uint32_t XdrReader::GetUint() {
  if (remaining() < 4) {
    throw Vxi11DecodeError("XDR: 4 bytes needed at offset " + std::to_string(pos_) + ", " +
                           std::to_string(remaining()) + " left");
  }
  const auto* p = reinterpret_cast<const unsigned char*>(in_.data() + pos_);
  pos_ += 4;
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3];
}

bool XdrReader::GetBool() {
  const size_t at = pos_;
  const uint32_t v = GetUint();
  if (v > 1) {
    throw Vxi11DecodeError("XDR: bool at offset " + std::to_string(at) + " is " +
                           std::to_string(v) + " (0 or 1 expected)");
  }
  return v == 1;
}

std::string XdrReader::GetOpaque(uint32_t max_length) {
  const size_t at = pos_;
  const uint32_t n = GetUint();
  if (n > max_length) {
    throw Vxi11DecodeError("XDR: opaque at offset " + std::to_string(at) + " has length " +
                           std::to_string(n) + " (at most " + std::to_string(max_length) + ")");
  }
  const uint64_t padded = uint64_t{n} + Padding(n);
  if (remaining() < padded) {
    throw Vxi11DecodeError("XDR: opaque at offset " + std::to_string(at) + " of " +
                           std::to_string(n) + " bytes, " + std::to_string(remaining()) + " left");
  }
  std::string out(in_.substr(pos_, n));
  pos_ += padded;
  return out;
}

std::string RecordMark(std::string_view record) {
  XdrWriter w;
  w.PutUint(0x80000000u | static_cast<uint32_t>(record.size()));
  std::string out = w.Take();
  out.append(record);
  return out;
}

void RecordAssembler::Feed(std::string_view bytes) {
  pending_.append(bytes);
  size_t pos = 0;
  while (pending_.size() - pos >= 4) {
    XdrReader r(std::string_view(pending_).substr(pos, 4));
    const uint32_t header = r.GetUint();
    const uint32_t length = header & 0x7fffffffu;
    const bool last = (header & 0x80000000u) != 0;
    if (record_.size() + length > max_) {
      throw Vxi11DecodeError("RPC record over " + std::to_string(max_) + " bytes (fragment of " +
                             std::to_string(length) + " after " + std::to_string(record_.size()) +
                             ")");
    }
    if (pending_.size() - pos - 4 < length) break;
    record_.append(pending_, pos + 4, length);
    pos += 4 + size_t{length};
    if (last) done_.push_back(std::move(record_)), record_.clear();
  }
  pending_.erase(0, pos);
}

std::optional<std::string> RecordAssembler::Next() {
  if (next_done_ == done_.size()) {
    done_.clear();
    next_done_ = 0;
    return std::nullopt;
  }
  return std::move(done_[next_done_++]);
}

RpcCall DecodeRpcCall(std::string_view record, std::optional<uint32_t>* xid) {
  XdrReader r(record);
  RpcCall c;
  c.xid = r.GetUint();
  if (xid) *xid = c.xid;
  const uint32_t type = r.GetUint();
  if (type != kMsgCall) {
    throw Vxi11DecodeError("RPC: msg_type " + std::to_string(type) + " is not CALL (0)");
  }
  c.rpc_version = r.GetUint();
  c.program = r.GetUint();
  c.version = r.GetUint();
  c.procedure = r.GetUint();
  SkipAuth(r, "credentials");
  SkipAuth(r, "verifier");
  c.args = std::string(r.Rest());
  return c;
}

std::string EncodeRpcCall(const RpcCall& call) {
  XdrWriter w;
  w.PutUint(call.xid);
  w.PutUint(kMsgCall);
  w.PutUint(call.rpc_version);
  w.PutUint(call.program);
  w.PutUint(call.version);
  w.PutUint(call.procedure);
  PutNullAuth(w);
  PutNullAuth(w);
  std::string out = w.Take();
  out.append(call.args);
  return out;
}

std::string EncodeAcceptedReply(uint32_t xid, AcceptStat stat, std::string_view results) {
  XdrWriter w;
  PutNullAuth(w);
  w.PutUint(stat);
  std::string out = ReplyHeader(xid, kMsgAccepted) + w.Take();
  out.append(results);
  return out;
}

std::string EncodeProgMismatchReply(uint32_t xid, uint32_t low, uint32_t high) {
  XdrWriter w;
  w.PutUint(low);
  w.PutUint(high);
  return EncodeAcceptedReply(xid, kProgMismatch, w.bytes());
}

std::string EncodeRpcMismatchReply(uint32_t xid) {
  XdrWriter w;
  w.PutUint(kRpcMismatch);
  w.PutUint(2);
  w.PutUint(2);
  return ReplyHeader(xid, kMsgDenied) + w.Take();
}

RpcReply DecodeRpcReply(std::string_view record) {
  XdrReader r(record);
  RpcReply reply;
  reply.xid = r.GetUint();
  if (r.GetUint() != kMsgReply) throw Vxi11DecodeError("RPC: not a REPLY");
  const uint32_t reply_stat = r.GetUint();
  reply.accepted = reply_stat == kMsgAccepted;
  if (reply.accepted) SkipAuth(r, "verifier");
  reply.stat = r.GetUint();
  reply.results = std::string(r.Rest());
  return reply;
}

PortMapping DecodePortMapping(std::string_view args) {
  XdrReader r(args);
  PortMapping m;
  m.program = r.GetUint();
  m.version = r.GetUint();
  m.protocol = r.GetUint();
  m.port = r.GetUint();
  return m;
}

std::string EncodePortMapping(const PortMapping& m) {
  XdrWriter w;
  w.PutUint(m.program);
  w.PutUint(m.version);
  w.PutUint(m.protocol);
  w.PutUint(m.port);
  return w.Take();
}

CreateLinkParms DecodeCreateLinkParms(std::string_view args) {
  XdrReader r(args);
  CreateLinkParms p;
  p.client_id = r.GetInt();
  p.lock_device = r.GetBool();
  p.lock_timeout_ms = r.GetUint();
  p.device = r.GetOpaque(256);
  return p;
}

DeviceWriteParms DecodeDeviceWriteParms(std::string_view args) {
  XdrReader r(args);
  DeviceWriteParms p;
  p.link_id = r.GetInt();
  p.io_timeout_ms = r.GetUint();
  p.lock_timeout_ms = r.GetUint();
  p.flags = r.GetInt();
  p.data = r.GetOpaque(kMaxWriteBytes);
  return p;
}

DeviceReadParms DecodeDeviceReadParms(std::string_view args) {
  XdrReader r(args);
  DeviceReadParms p;
  p.link_id = r.GetInt();
  p.request_size = r.GetUint();
  p.io_timeout_ms = r.GetUint();
  p.lock_timeout_ms = r.GetUint();
  p.flags = r.GetInt();
  p.term_char = r.GetInt();
  return p;
}

DeviceGenericParms DecodeDeviceGenericParms(std::string_view args) {
  XdrReader r(args);
  DeviceGenericParms p;
  p.link_id = r.GetInt();
  p.flags = r.GetInt();
  p.lock_timeout_ms = r.GetUint();
  p.io_timeout_ms = r.GetUint();
  return p;
}

DeviceLockParms DecodeDeviceLockParms(std::string_view args) {
  XdrReader r(args);
  DeviceLockParms p;
  p.link_id = r.GetInt();
  p.flags = r.GetInt();
  p.lock_timeout_ms = r.GetUint();
  return p;
}

DeviceEnableSrqParms DecodeDeviceEnableSrqParms(std::string_view args) {
  XdrReader r(args);
  DeviceEnableSrqParms p;
  p.link_id = r.GetInt();
  p.enable = r.GetBool();
  p.handle = r.GetOpaque(40);
  return p;
}

DeviceRemoteFunc DecodeDeviceRemoteFunc(std::string_view args) {
  XdrReader r(args);
  DeviceRemoteFunc f;
  f.host_addr = r.GetUint();
  f.host_port = r.GetUint();
  f.prog_num = r.GetUint();
  f.prog_vers = r.GetUint();
  f.prog_family = r.GetInt();
  return f;
}

int32_t DecodeDeviceLink(std::string_view args) {
  XdrReader r(args);
  return r.GetInt();
}

std::string EncodeCreateLinkParms(const CreateLinkParms& p) {
  XdrWriter w;
  w.PutInt(p.client_id);
  w.PutBool(p.lock_device);
  w.PutUint(p.lock_timeout_ms);
  w.PutOpaque(p.device);
  return w.Take();
}

std::string EncodeDeviceWriteParms(const DeviceWriteParms& p) {
  XdrWriter w;
  w.PutInt(p.link_id);
  w.PutUint(p.io_timeout_ms);
  w.PutUint(p.lock_timeout_ms);
  w.PutInt(p.flags);
  w.PutOpaque(p.data);
  return w.Take();
}

std::string EncodeDeviceReadParms(const DeviceReadParms& p) {
  XdrWriter w;
  w.PutInt(p.link_id);
  w.PutUint(p.request_size);
  w.PutUint(p.io_timeout_ms);
  w.PutUint(p.lock_timeout_ms);
  w.PutInt(p.flags);
  w.PutInt(p.term_char);
  return w.Take();
}

std::string EncodeDeviceGenericParms(const DeviceGenericParms& p) {
  XdrWriter w;
  w.PutInt(p.link_id);
  w.PutInt(p.flags);
  w.PutUint(p.lock_timeout_ms);
  w.PutUint(p.io_timeout_ms);
  return w.Take();
}

std::string EncodeDeviceLockParms(const DeviceLockParms& p) {
  XdrWriter w;
  w.PutInt(p.link_id);
  w.PutInt(p.flags);
  w.PutUint(p.lock_timeout_ms);
  return w.Take();
}

std::string EncodeDeviceLink(int32_t link_id) {
  XdrWriter w;
  w.PutInt(link_id);
  return w.Take();
}

std::string EncodeCreateLinkResp(const CreateLinkResp& r) {
  XdrWriter w;
  w.PutInt(r.error);
  w.PutInt(r.link_id);
  w.PutUint(r.abort_port);
  w.PutUint(r.max_recv_size);
  return w.Take();
}

std::string EncodeDeviceWriteResp(const DeviceWriteResp& r) {
  XdrWriter w;
  w.PutInt(r.error);
  w.PutUint(r.size);
  return w.Take();
}

std::string EncodeDeviceReadResp(const DeviceReadResp& r) {
  XdrWriter w;
  w.PutInt(r.error);
  w.PutInt(r.reason);
  w.PutOpaque(r.data);
  return w.Take();
}

std::string EncodeDeviceReadStbResp(const DeviceReadStbResp& r) {
  XdrWriter w;
  w.PutInt(r.error);
  w.PutUint(r.stb);
  return w.Take();
}

std::string EncodeDeviceError(int32_t error) {
  XdrWriter w;
  w.PutInt(error);
  return w.Take();
}

CreateLinkResp DecodeCreateLinkResp(std::string_view results) {
  XdrReader r(results);
  CreateLinkResp out;
  out.error = r.GetInt();
  out.link_id = r.GetInt();
  out.abort_port = r.GetUint();
  out.max_recv_size = r.GetUint();
  return out;
}

DeviceWriteResp DecodeDeviceWriteResp(std::string_view results) {
  XdrReader r(results);
  DeviceWriteResp out;
  out.error = r.GetInt();
  out.size = r.GetUint();
  return out;
}

DeviceReadResp DecodeDeviceReadResp(std::string_view results) {
  XdrReader r(results);
  DeviceReadResp out;
  out.error = r.GetInt();
  out.reason = r.GetInt();
  out.data = r.GetOpaque(0xffffffffu);
  return out;
}

DeviceReadStbResp DecodeDeviceReadStbResp(std::string_view results) {
  XdrReader r(results);
  DeviceReadStbResp out;
  out.error = r.GetInt();
  out.stb = r.GetUint();
  return out;
}

int32_t DecodeDeviceError(std::string_view results) {
  XdrReader r(results);
  return r.GetInt();
}

}  // namespace msmcal::sim::vxi11
