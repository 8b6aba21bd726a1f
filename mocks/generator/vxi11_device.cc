#include "mocks/generator/vxi11_device.h"

#include <algorithm>
#include <cctype>
#include <vector>

namespace msmcal::sim {

using namespace vxi11;

namespace {

bool IsInstrumentName(const std::string& device) {
  std::string lower = device;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return lower == "inst0";
}

}  // namespace

Vxi11Device::Vxi11Device(Mock33520B& unit, Vxi11DeviceOptions options)
    : unit_(unit), options_(options) {}

void Vxi11Device::SetPorts(uint32_t core_port, uint32_t abort_port) {
  options_.core_port = core_port;
  options_.abort_port = abort_port;
}

std::optional<std::string> Vxi11Device::Handle(Vxi11Channel channel, std::string_view record,
                                               uint64_t connection) {
  ++stats_.calls;
  std::optional<uint32_t> xid;
  RpcCall call;
  try {
    call = DecodeRpcCall(record, &xid);
  } catch (const Vxi11DecodeError&) {
    ++stats_.garbage;
    if (!xid) return std::nullopt;
    return EncodeAcceptedReply(*xid, kGarbageArgs);
  }
  if (call.rpc_version != 2) return EncodeRpcMismatchReply(call.xid);
  const uint32_t program = channel == Vxi11Channel::kPortmapper ? kPortmapperProgram
                           : channel == Vxi11Channel::kCore     ? kCoreProgram
                                                                : kAbortProgram;
  const uint32_t version =
      channel == Vxi11Channel::kPortmapper ? kPortmapperVersion : kVxi11Version;
  if (call.program != program) return EncodeAcceptedReply(call.xid, kProgUnavail);
  if (call.version != version) return EncodeProgMismatchReply(call.xid, version, version);
  try {
    switch (channel) {
      case Vxi11Channel::kPortmapper:
        return Portmapper(call);
      case Vxi11Channel::kCore:
        return Core(call, connection);
      case Vxi11Channel::kAbort:
        return Abort(call);
    }
  } catch (const Vxi11DecodeError&) {
    ++stats_.garbage;
  }
  return EncodeAcceptedReply(call.xid, kGarbageArgs);
}

std::string Vxi11Device::Portmapper(const RpcCall& call) {
  if (call.procedure == kPmapProcNull) return EncodeAcceptedReply(call.xid, kSuccess);
  if (call.procedure != kPmapProcGetPort) return EncodeAcceptedReply(call.xid, kProcUnavail);
  const PortMapping m = DecodePortMapping(call.args);
  uint32_t port = 0;  // not registered
  if (m.version == kVxi11Version && m.protocol == kIpProtoTcp) {
    if (m.program == kCoreProgram) port = options_.core_port;
    if (m.program == kAbortProgram) port = options_.abort_port;
  }
  XdrWriter w;
  w.PutUint(port);
  return EncodeAcceptedReply(call.xid, kSuccess, w.bytes());
}

std::string Vxi11Device::Abort(const RpcCall& call) {
  if (call.procedure == kProcNull) return EncodeAcceptedReply(call.xid, kSuccess);
  if (call.procedure != kDeviceAbort) return EncodeAcceptedReply(call.xid, kProcUnavail);
  const int32_t link = DecodeDeviceLink(call.args);
  // Every operation completes when it arrives: there is never one in progress to abort.
  return EncodeAcceptedReply(call.xid, kSuccess,
                             EncodeDeviceError(Find(link) ? kNoError : kInvalidLinkId));
}

Vxi11Device::Link* Vxi11Device::Find(int32_t link_id) {
  auto it = links_.find(link_id);
  return it == links_.end() ? nullptr : &it->second;
}

std::string Vxi11Device::Core(const RpcCall& call, uint64_t connection) {
  auto ok = [&](const std::string& results) {
    return EncodeAcceptedReply(call.xid, kSuccess, results);
  };
  auto error = [&](int32_t e) { return ok(EncodeDeviceError(e)); };
  switch (call.procedure) {
    case kProcNull:
      return EncodeAcceptedReply(call.xid, kSuccess);
    case kCreateLink:
      return ok(CreateLink(DecodeCreateLinkParms(call.args), connection));
    case kDeviceWrite:
      return ok(Write(DecodeDeviceWriteParms(call.args)));
    case kDeviceRead:
      return ok(Read(DecodeDeviceReadParms(call.args)));
    case kDeviceReadStb: {
      const DeviceGenericParms p = DecodeDeviceGenericParms(call.args);
      Link* link = Find(p.link_id);
      DeviceReadStbResp r;
      if (!link) {
        r.error = kInvalidLinkId;
      } else if (LockedByOther(p.link_id)) {
        r.error = kDeviceLocked;
      } else {
        uint32_t stb = 0;
        try {
          stb = static_cast<uint32_t>(std::stoi(unit_.Process("*STB?"))) & 0xff;
        } catch (const std::exception&) {
        }
        if (!link->replies.empty()) stb |= 0x10;  // MAV: a reply waits on this link
        r.stb = stb;
      }
      return ok(EncodeDeviceReadStbResp(r));
    }
    case kDeviceTrigger:
    case kDeviceClear:
    case kDeviceRemote:
    case kDeviceLocal: {
      const DeviceGenericParms p = DecodeDeviceGenericParms(call.args);
      Link* link = Find(p.link_id);
      if (!link) return error(kInvalidLinkId);
      if (LockedByOther(p.link_id)) return error(kDeviceLocked);
      if (call.procedure == kDeviceTrigger) {
        Execute(*link, "*TRG");
      } else if (call.procedure == kDeviceClear) {
        link->input.clear();
        link->framer = MessageFramer();
        link->discarding = false;
        link->replies.clear();
        link->reply_offset = 0;
      }
      return error(kNoError);
    }
    case kDeviceLock: {
      const DeviceLockParms p = DecodeDeviceLockParms(call.args);
      if (!Find(p.link_id)) return error(kInvalidLinkId);
      if (LockedByOther(p.link_id)) return error(kDeviceLocked);
      lock_owner_ = p.link_id;
      return error(kNoError);
    }
    case kDeviceUnlock: {
      const int32_t id = DecodeDeviceLink(call.args);
      if (!Find(id)) return error(kInvalidLinkId);
      if (lock_owner_ != id) return error(kNoLockHeld);
      lock_owner_.reset();
      return error(kNoError);
    }
    case kDeviceEnableSrq: {
      const DeviceEnableSrqParms p = DecodeDeviceEnableSrqParms(call.args);
      return error(Find(p.link_id) ? kOperationNotSupported : kInvalidLinkId);
    }
    case kDeviceDocmd: {
      XdrReader r(call.args);
      const int32_t id = r.GetInt();
      XdrWriter w;
      w.PutInt(Find(id) ? kOperationNotSupported : kInvalidLinkId);
      w.PutOpaque({});
      return ok(w.Take());
    }
    case kDestroyLink: {
      const int32_t id = DecodeDeviceLink(call.args);
      if (!Find(id)) return error(kInvalidLinkId);
      Destroy(id);
      return error(kNoError);
    }
    case kCreateIntrChan:
      DecodeDeviceRemoteFunc(call.args);
      return error(kOperationNotSupported);
    case kDestroyIntrChan:
      return error(kChannelNotEstablished);
    default:
      return EncodeAcceptedReply(call.xid, kProcUnavail);
  }
}

std::string Vxi11Device::CreateLink(const CreateLinkParms& p, uint64_t connection) {
  CreateLinkResp r;
  r.abort_port = options_.abort_port;
  r.max_recv_size = options_.max_recv_size;
  if (!IsInstrumentName(p.device)) {
    r.error = kDeviceNotAccessible;
    return EncodeCreateLinkResp(r);
  }
  if (p.lock_device && lock_owner_) {
    r.error = kDeviceLocked;
    return EncodeCreateLinkResp(r);
  }
  const int32_t id = next_link_id_++;
  if (next_link_id_ < 1) next_link_id_ = 1;  // wrapped
  links_[id].connection = connection;
  if (p.lock_device) lock_owner_ = id;
  ++stats_.links_created;
  r.link_id = id;
  return EncodeCreateLinkResp(r);
}

std::string Vxi11Device::Write(const DeviceWriteParms& p) {
  DeviceWriteResp r;
  Link* link = Find(p.link_id);
  if (!link) {
    r.error = kInvalidLinkId;
    return EncodeDeviceWriteResp(r);
  }
  if (LockedByOther(p.link_id)) {
    r.error = kDeviceLocked;
    return EncodeDeviceWriteResp(r);
  }
  link->input.append(p.data);
  size_t start = 0;
  while (const auto end = link->framer.Next(link->input)) {
    std::string message = link->input.substr(start, *end - start);
    start = *end + 1;
    link->framer.Reset(start);
    if (link->discarding) {
      link->discarding = false;
    } else {
      Execute(*link, std::move(message));
    }
  }
  link->input.erase(0, start);
  link->framer.Shift(start);
  if (link->input.size() > options_.max_message_bytes) {
    if (!link->discarding) unit_.ReportInputOverrun();
    link->discarding = true;
    link->input.clear();
    link->framer = MessageFramer();
  }
  if ((p.flags & kFlagEnd) != 0) {
    if (!link->discarding && !link->input.empty()) Execute(*link, link->input);
    link->input.clear();
    link->framer = MessageFramer();
    link->discarding = false;
  }
  r.size = static_cast<uint32_t>(p.data.size());
  return EncodeDeviceWriteResp(r);
}

void Vxi11Device::Execute(Link& link, std::string message) {
  ++stats_.messages;
  std::string reply = unit_.Process(message);
  if (reply.empty()) return;
  reply.push_back('\n');
  link.replies.push_back(std::move(reply));
}

std::string Vxi11Device::Read(const DeviceReadParms& p) {
  DeviceReadResp r;
  Link* link = Find(p.link_id);
  if (!link) {
    r.error = kInvalidLinkId;
  } else if (LockedByOther(p.link_id)) {
    r.error = kDeviceLocked;
  } else if (link->replies.empty()) {
    r.error = kIoTimeout;
  } else {
    const std::string& reply = link->replies.front();
    const size_t left = reply.size() - link->reply_offset;
    size_t n = std::min<size_t>(left, p.request_size);
    if ((p.flags & kFlagTermCharSet) != 0) {
      const size_t at = reply.find(static_cast<char>(p.term_char), link->reply_offset);
      if (at != std::string::npos && at - link->reply_offset < n) {
        n = at - link->reply_offset + 1;
        r.reason |= kReasonTermChar;
      }
    }
    r.data = reply.substr(link->reply_offset, n);
    link->reply_offset += n;
    if (link->reply_offset == reply.size()) {
      r.reason |= kReasonEnd;
      link->replies.pop_front();
      link->reply_offset = 0;
    } else if (n == p.request_size) {
      r.reason |= kReasonRequestCount;
    }
  }
  return EncodeDeviceReadResp(r);
}

void Vxi11Device::Destroy(int32_t link_id) {
  links_.erase(link_id);
  if (lock_owner_ == link_id) lock_owner_.reset();
}

void Vxi11Device::ConnectionClosed(uint64_t connection) {
  std::vector<int32_t> ids;
  for (const auto& [id, link] : links_) {
    if (link.connection == connection) ids.push_back(id);
  }
  for (int32_t id : ids) Destroy(id);
}

}  // namespace msmcal::sim
