// libFuzzer target: the mock 33520B's VXI-11 decoder (mocks/generator/vxi11_protocol.h) and the
// device layer behind it (vxi11_device.h): the bytes a client sends on a core channel.
//
// Input: byte 0 sets the chunk size the stream is fed in, byte 1 the channel (core, abort,
// portmapper); the rest is a TCP byte stream with record marking. Checks:
// - RecordAssembler returns records or throws Vxi11DecodeError (an oversized record), never
//   holds more than its bound plus one fragment header;
// - every record is answered (or dropped when it has no xid) without an exception, and the
//   reply decodes as an RPC reply with the call's xid;
// - each struct decoder returns or throws Vxi11DecodeError, and what it returns re-encodes and
//   decodes to the same fields (Decode(Encode(x)) == x).
#include <cstdint>
#include <string>

#include "fuzz/fuzz_util.h"
#include "mocks/generator/vxi11_device.h"
#include "mocks/generator/vxi11_protocol.h"

using namespace msmcal;
using namespace msmcal::sim::vxi11;
using fuzz::Check;

namespace {

constexpr size_t kMaxRecord = 1 << 16;

template <typename F>
void Decodes(F&& f) {
  try {
    f();
  } catch (const Vxi11DecodeError&) {
  }
}

void CheckStructs(const std::string& args) {
  Decodes([&] {
    const CreateLinkParms p = DecodeCreateLinkParms(args);
    const CreateLinkParms q = DecodeCreateLinkParms(EncodeCreateLinkParms(p));
    Check(p.client_id == q.client_id && p.lock_device == q.lock_device &&
              p.lock_timeout_ms == q.lock_timeout_ms && p.device == q.device,
          "create_link round trip");
  });
  Decodes([&] {
    const DeviceWriteParms p = DecodeDeviceWriteParms(args);
    const DeviceWriteParms q = DecodeDeviceWriteParms(EncodeDeviceWriteParms(p));
    Check(p.link_id == q.link_id && p.flags == q.flags && p.data == q.data &&
              p.io_timeout_ms == q.io_timeout_ms,
          "device_write round trip");
  });
  Decodes([&] {
    const DeviceReadParms p = DecodeDeviceReadParms(args);
    const DeviceReadParms q = DecodeDeviceReadParms(EncodeDeviceReadParms(p));
    Check(p.link_id == q.link_id && p.request_size == q.request_size && p.flags == q.flags &&
              p.term_char == q.term_char,
          "device_read round trip");
  });
  Decodes([&] {
    const DeviceReadResp r = DecodeDeviceReadResp(args);
    Check(DecodeDeviceReadResp(EncodeDeviceReadResp(r)).data == r.data, "read resp round trip");
  });
  Decodes([&] { DecodeDeviceGenericParms(args); });
  Decodes([&] { DecodeDeviceLockParms(args); });
  Decodes([&] { DecodeDeviceEnableSrqParms(args); });
  Decodes([&] { DecodeDeviceRemoteFunc(args); });
  Decodes([&] { DecodePortMapping(args); });
  Decodes([&] { DecodeRpcReply(args); });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  const size_t chunk = 1 + data[0] % 64;
  const sim::Vxi11Channel channel = data[1] % 3 == 0   ? sim::Vxi11Channel::kCore
                                    : data[1] % 3 == 1 ? sim::Vxi11Channel::kAbort
                                                       : sim::Vxi11Channel::kPortmapper;
  const std::string stream(reinterpret_cast<const char*>(data + 2), size - 2);
  sim::UnitOptions options;
  options.arb_memory_points = 4096;
  options.max_response_bytes = 1 << 16;
  sim::Mock33520B unit(options, [] { return int64_t{0}; });
  sim::Vxi11DeviceOptions device_options;
  device_options.max_message_bytes = 1 << 16;
  sim::Vxi11Device device(unit, device_options);
  RecordAssembler records(kMaxRecord);
  for (size_t at = 0; at < stream.size(); at += chunk) {
    try {
      records.Feed(std::string_view(stream).substr(at, chunk));
    } catch (const Vxi11DecodeError&) {
      break;  // the server closes such a connection
    }
    Check(records.buffered() <= kMaxRecord + 2 * 64 + 4, "assembler buffering unbounded");
    while (std::optional<std::string> record = records.Next()) {
      std::optional<uint32_t> xid;
      Decodes([&] { CheckStructs(DecodeRpcCall(*record, &xid).args); });
      const std::optional<std::string> reply = device.Handle(channel, *record, /*connection=*/1);
      Check(reply.has_value() == xid.has_value(), "a call with an xid is answered");
      if (reply) Check(DecodeRpcReply(*reply).xid == *xid, "reply xid");
    }
  }
  device.ConnectionClosed(1);
  Check(device.LinkCount() == 0, "links survive their connection");
  return 0;
}
