// The VXI-11 device layer as transcripts: call records in, reply records out, no sockets.
#include "mocks/generator/vxi11_device.h"

#include <gtest/gtest.h>

#include <string>

namespace msmcal::sim {
namespace {

using namespace vxi11;

class Vxi11DeviceTest : public ::testing::Test {
 protected:
  Vxi11DeviceTest() : unit_(UnitOptions{}, [] { return int64_t{0}; }), device_(unit_, Options()) {}

  static Vxi11DeviceOptions Options() {
    Vxi11DeviceOptions o;
    o.core_port = 1024;
    o.abort_port = 1025;
    return o;
  }

  // Calls `proc` of the core channel; returns the SUCCESS results (fails the test otherwise).
  std::string Call(uint32_t proc, const std::string& args, uint64_t connection = 1,
                   Vxi11Channel channel = Vxi11Channel::kCore) {
    RpcCall c;
    c.xid = ++xid_;
    c.program = channel == Vxi11Channel::kCore    ? kCoreProgram
                : channel == Vxi11Channel::kAbort ? kAbortProgram
                                                  : kPortmapperProgram;
    c.version = channel == Vxi11Channel::kPortmapper ? 2 : 1;
    c.procedure = proc;
    c.args = args;
    const std::optional<std::string> reply = device_.Handle(channel, EncodeRpcCall(c), connection);
    EXPECT_TRUE(reply);
    const RpcReply r = DecodeRpcReply(reply.value_or(""));
    EXPECT_EQ(r.xid, xid_);
    EXPECT_TRUE(r.accepted);
    EXPECT_EQ(r.stat, uint32_t{kSuccess});
    return r.results;
  }

  int32_t Link(uint64_t connection = 1, bool lock = false) {
    const CreateLinkResp r = DecodeCreateLinkResp(
        Call(kCreateLink, EncodeCreateLinkParms({7, lock, 0, "inst0"}), connection));
    EXPECT_EQ(r.error, kNoError);
    EXPECT_EQ(r.abort_port, 1025u);
    EXPECT_EQ(r.max_recv_size, kMaxWriteBytes);
    return r.link_id;
  }

  DeviceWriteResp Write(int32_t link, const std::string& data, int32_t flags = kFlagEnd) {
    return DecodeDeviceWriteResp(
        Call(kDeviceWrite, EncodeDeviceWriteParms({link, 1000, 0, flags, data})));
  }

  DeviceReadResp Read(int32_t link, uint32_t size = 4096, int32_t flags = 0, int32_t term = 0) {
    return DecodeDeviceReadResp(
        Call(kDeviceRead, EncodeDeviceReadParms({link, size, 1000, 0, flags, term})));
  }

  Mock33520B unit_;
  Vxi11Device device_;
  uint32_t xid_ = 100;
};

TEST_F(Vxi11DeviceTest, PortmapperMapsCoreAndAbortPrograms) {
  auto port = [&](uint32_t prog, uint32_t vers, uint32_t prot) {
    XdrReader r(Call(kPmapProcGetPort, EncodePortMapping({prog, vers, prot, 0}), 0,
                     Vxi11Channel::kPortmapper));
    return r.GetUint();
  };
  EXPECT_EQ(port(kCoreProgram, 1, kIpProtoTcp), 1024u);
  EXPECT_EQ(port(kAbortProgram, 1, kIpProtoTcp), 1025u);
  EXPECT_EQ(port(kCoreProgram, 1, kIpProtoUdp), 0u);  // not registered
  EXPECT_EQ(port(kCoreProgram, 2, kIpProtoTcp), 0u);
  EXPECT_EQ(port(12345, 1, kIpProtoTcp), 0u);
  EXPECT_EQ(Call(kPmapProcNull, "", 0, Vxi11Channel::kPortmapper), "");
}

TEST_F(Vxi11DeviceTest, WriteThenReadIdnWithEnd) {
  const int32_t link = Link();
  const DeviceWriteResp w = Write(link, "*IDN?\n");
  EXPECT_EQ(w.error, kNoError);
  EXPECT_EQ(w.size, 6u);
  const DeviceReadResp r = Read(link);
  EXPECT_EQ(r.error, kNoError);
  EXPECT_EQ(r.reason, kReasonEnd);
  EXPECT_EQ(r.data, UnitOptions{}.identity + "\n");
  // Nothing queued: I/O timeout at once.
  EXPECT_EQ(Read(link).error, kIoTimeout);
}

TEST_F(Vxi11DeviceTest, ReadHonoursRequestSizeAndTermChar) {
  const int32_t link = Link();
  Write(link, "*IDN?");  // no '\n': END ends the message
  const std::string idn = UnitOptions{}.identity + "\n";
  DeviceReadResp r = Read(link, 5);
  EXPECT_EQ(r.reason, kReasonRequestCount);
  EXPECT_EQ(r.data, idn.substr(0, 5));
  r = Read(link, 4096, kFlagTermCharSet, ',');
  EXPECT_EQ(r.reason, kReasonTermChar);
  EXPECT_EQ(r.data, idn.substr(5, idn.find(',') - 5 + 1));
  r = Read(link);
  EXPECT_EQ(r.reason, kReasonEnd);
  EXPECT_EQ(r.data, idn.substr(idn.find(',') + 1));
}

TEST_F(Vxi11DeviceTest, MessageSpansWritesUntilEnd) {
  const int32_t link = Link();
  // A definite-length block split across writes; '\n' inside it does not end the message.
  // 8 points (the 33520B's minimum) of 0x0A0A.
  EXPECT_EQ(Write(link, "SOUR1:DATA:ARB:DAC W,#216" + std::string(8, '\n'), 0).error, kNoError);
  EXPECT_EQ(Write(link, std::string(8, '\n'), 0).error, kNoError);
  EXPECT_EQ(Write(link, ";:SYST:ERR?", kFlagEnd).error, kNoError);
  EXPECT_EQ(Read(link).data, "+0,\"No error\"\n");
  Write(link, "SOUR1:DATA:ATTR:POIN? W\nSOUR1:FUNC?\n");  // two messages, two replies
  EXPECT_EQ(Read(link).data, "+8\n");
  EXPECT_EQ(Read(link).data, "SIN\n");
}

TEST_F(Vxi11DeviceTest, DeviceClearDropsInputAndReplies) {
  const int32_t link = Link();
  Write(link, "*IDN?\n");
  Write(link, "SOUR1:FREQ 5", 0);  // incomplete
  EXPECT_EQ(DecodeDeviceError(Call(kDeviceClear, EncodeDeviceGenericParms({link, 0, 0, 1000}))),
            kNoError);
  EXPECT_EQ(Read(link).error, kIoTimeout);
  Write(link, "SYST:ERR?");
  EXPECT_EQ(Read(link).data, "+0,\"No error\"\n");
}

TEST_F(Vxi11DeviceTest, ReadStbSetsMavWhileAReplyWaits) {
  const int32_t link = Link();
  auto stb = [&] {
    return DecodeDeviceReadStbResp(
        Call(kDeviceReadStb, EncodeDeviceGenericParms({link, 0, 0, 1000})));
  };
  EXPECT_EQ(stb().stb, 0u);
  Write(link, "*IDN?");
  EXPECT_EQ(stb().stb, 0x10u);
}

TEST_F(Vxi11DeviceTest, UnknownLinkIdAnswersError4) {
  EXPECT_EQ(Write(99, "*IDN?").error, kInvalidLinkId);
  EXPECT_EQ(Read(99).error, kInvalidLinkId);
  const std::string generic = EncodeDeviceGenericParms({99, 0, 0, 0});
  for (uint32_t proc : {kDeviceTrigger, kDeviceClear, kDeviceRemote, kDeviceLocal}) {
    EXPECT_EQ(DecodeDeviceError(Call(proc, generic)), kInvalidLinkId) << proc;
  }
  EXPECT_EQ(DecodeDeviceReadStbResp(Call(kDeviceReadStb, generic)).error, kInvalidLinkId);
  EXPECT_EQ(DecodeDeviceError(Call(kDestroyLink, EncodeDeviceLink(99))), kInvalidLinkId);
  EXPECT_EQ(DecodeDeviceError(Call(kDeviceAbort, EncodeDeviceLink(99), 2, Vxi11Channel::kAbort)),
            kInvalidLinkId);
}

TEST_F(Vxi11DeviceTest, LockKeepsOtherLinksOut) {
  const int32_t a = Link(1), b = Link(2);
  EXPECT_EQ(DecodeDeviceError(Call(kDeviceLock, EncodeDeviceLockParms({a, 0, 0}))), kNoError);
  EXPECT_EQ(Write(b, "*IDN?").error, kDeviceLocked);
  EXPECT_EQ(DecodeDeviceError(Call(kDeviceLock, EncodeDeviceLockParms({b, 0, 0}))), kDeviceLocked);
  EXPECT_EQ(DecodeDeviceError(Call(kDeviceUnlock, EncodeDeviceLink(b))), kNoLockHeld);
  EXPECT_EQ(Write(a, "*IDN?").error, kNoError);
  // The lock goes with its connection.
  device_.ConnectionClosed(1);
  EXPECT_EQ(device_.LinkCount(), 1u);
  EXPECT_EQ(Write(b, "*IDN?").error, kNoError);
  EXPECT_EQ(Write(a, "*IDN?").error, kInvalidLinkId);
}

TEST_F(Vxi11DeviceTest, CreateLinkNeedsInst0) {
  const CreateLinkResp r =
      DecodeCreateLinkResp(Call(kCreateLink, EncodeCreateLinkParms({7, false, 0, "gpib0,5"})));
  EXPECT_EQ(r.error, kDeviceNotAccessible);
  EXPECT_EQ(device_.LinkCount(), 0u);
}

TEST_F(Vxi11DeviceTest, MalformedCallsGetRpcErrorsByteExact) {
  // Too short for an xid: no reply.
  EXPECT_FALSE(device_.Handle(Vxi11Channel::kCore, std::string("\0\0", 2), 1));
  // A header cut after the xid: GARBAGE_ARGS.
  EXPECT_EQ(device_.Handle(Vxi11Channel::kCore, std::string("\0\0\0\x1a\0\0", 6), 1),
            EncodeAcceptedReply(0x1a, kGarbageArgs));
  RpcCall c;
  c.xid = 5;
  c.program = kCoreProgram;
  c.version = 1;
  c.procedure = kDeviceWrite;
  c.args = EncodeDeviceLink(1);  // device_write's arguments cut short
  EXPECT_EQ(device_.Handle(Vxi11Channel::kCore, EncodeRpcCall(c), 1),
            EncodeAcceptedReply(5, kGarbageArgs));
  c.procedure = 77;
  EXPECT_EQ(device_.Handle(Vxi11Channel::kCore, EncodeRpcCall(c), 1),
            EncodeAcceptedReply(5, kProcUnavail));
  c.version = 3;
  EXPECT_EQ(device_.Handle(Vxi11Channel::kCore, EncodeRpcCall(c), 1),
            EncodeProgMismatchReply(5, 1, 1));
  c.program = kPortmapperProgram;
  EXPECT_EQ(device_.Handle(Vxi11Channel::kCore, EncodeRpcCall(c), 1),
            EncodeAcceptedReply(5, kProgUnavail));
  c.rpc_version = 3;
  EXPECT_EQ(device_.Handle(Vxi11Channel::kCore, EncodeRpcCall(c), 1), EncodeRpcMismatchReply(5));
  EXPECT_EQ(device_.stats().garbage, 2u + 1u);
}

TEST_F(Vxi11DeviceTest, SameInstrumentAsTheRawSocket) {
  const int32_t link = Link();
  Write(link, "SOUR2:FREQ 1234");
  EXPECT_DOUBLE_EQ(unit_.Signal(2).frequency_hz, 1234.0);
  unit_.Process("SOUR2:VOLT 0.5");
  Write(link, "SOUR2:VOLT?");
  EXPECT_EQ(Read(link).data, "+5.0000000000000E-01\n");
}

}  // namespace
}  // namespace msmcal::sim
