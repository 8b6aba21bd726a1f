// VXI-11 protocol layer: byte-exact encodings. The call vectors are what pyvisa-py's rpc.py /
// vxi11.py pack (Vxi11Packer.pack_callheader + pack_*_parms, AUTH_NONE), as hex.
#include "mocks/generator/vxi11_protocol.h"

#include <gtest/gtest.h>

#include <string>

namespace msmcal::sim::vxi11 {
namespace {

std::string Hex(const std::string& hex) {
  std::string out;
  for (size_t i = 0; i + 1 < hex.size(); i += 2) {
    out.push_back(static_cast<char>(std::stoi(hex.substr(i, 2), nullptr, 16)));
  }
  return out;
}

// pyvisa-py: create_link(client_id=42, lock_device=False, lock_timeout=0, "inst0"), xid 0x1234.
const char* kCreateLinkCall =
    "000012340000000000000002000607af000000010000000a000000000000000000000000000000000000002a"
    "000000000000000000000005696e737430000000";
// device_write(link 1, io_timeout 5000, lock_timeout 0, flags END, "*IDN?\n"), xid 0x1235.
const char* kWriteCall =
    "000012350000000000000002000607af000000010000000b0000000000000000000000000000000000000001"
    "000013880000000000000008000000062a49444e3f0a0000";
// device_read(link 1, requestSize 1024, io_timeout 5000, lock 0, TERMCHAR_SET, '\n'), 0x1236.
const char* kReadCall =
    "000012360000000000000002000607af000000010000000c0000000000000000000000000000000000000001"
    "000004000000138800000000000000800000000a";
// Portmapper GETPORT(DEVICE_CORE, 1, TCP, 0), xid 7.
const char* kGetPortCall =
    "000000070000000000000002000186a0000000020000000300000000000000000000000000000000000607af"
    "000000010000000600000000";

TEST(Vxi11Xdr, UintsBigEndianOpaquePadded) {
  XdrWriter w;
  w.PutUint(0x0607AF);
  w.PutInt(-1);
  w.PutBool(true);
  w.PutOpaque("inst0");
  w.PutOpaque("");
  w.PutOpaque("abcd");
  EXPECT_EQ(w.bytes(),
            Hex("000607afffffffff0000000100000005696e737430000000000000000000000461626364"));
  XdrReader r(w.bytes());
  EXPECT_EQ(r.GetUint(), 0x0607AFu);
  EXPECT_EQ(r.GetInt(), -1);
  EXPECT_TRUE(r.GetBool());
  EXPECT_EQ(r.GetOpaque(16), "inst0");
  EXPECT_EQ(r.GetOpaque(16), "");
  EXPECT_EQ(r.GetOpaque(16), "abcd");
  EXPECT_EQ(r.remaining(), 0u);
  EXPECT_THROW(r.GetUint(), Vxi11DecodeError);
}

TEST(Vxi11Xdr, RejectsShortOverlongAndBadBool) {
  EXPECT_THROW(XdrReader(Hex("000001")).GetUint(), Vxi11DecodeError);
  EXPECT_THROW(XdrReader(Hex("00000002")).GetBool(), Vxi11DecodeError);
  EXPECT_THROW(XdrReader(Hex("0000000561626364")).GetOpaque(16), Vxi11DecodeError);    // short
  EXPECT_THROW(XdrReader(Hex("000000056162636465")).GetOpaque(16), Vxi11DecodeError);  // no pad
  EXPECT_THROW(XdrReader(Hex("0000001100")).GetOpaque(16), Vxi11DecodeError);          // over max
  EXPECT_THROW(XdrReader(Hex("ffffffff")).GetOpaque(0xffffffffu), Vxi11DecodeError);
}

TEST(Vxi11Rpc, DecodesPyvisaCalls) {
  const RpcCall c = DecodeRpcCall(Hex(kCreateLinkCall));
  EXPECT_EQ(c.xid, 0x1234u);
  EXPECT_EQ(c.rpc_version, 2u);
  EXPECT_EQ(c.program, kCoreProgram);
  EXPECT_EQ(c.version, 1u);
  EXPECT_EQ(c.procedure, uint32_t{kCreateLink});
  const CreateLinkParms p = DecodeCreateLinkParms(c.args);
  EXPECT_EQ(p.client_id, 42);
  EXPECT_FALSE(p.lock_device);
  EXPECT_EQ(p.lock_timeout_ms, 0u);
  EXPECT_EQ(p.device, "inst0");

  const DeviceWriteParms w = DecodeDeviceWriteParms(DecodeRpcCall(Hex(kWriteCall)).args);
  EXPECT_EQ(w.link_id, 1);
  EXPECT_EQ(w.io_timeout_ms, 5000u);
  EXPECT_EQ(w.flags, kFlagEnd);
  EXPECT_EQ(w.data, "*IDN?\n");

  const DeviceReadParms r = DecodeDeviceReadParms(DecodeRpcCall(Hex(kReadCall)).args);
  EXPECT_EQ(r.link_id, 1);
  EXPECT_EQ(r.request_size, 1024u);
  EXPECT_EQ(r.io_timeout_ms, 5000u);
  EXPECT_EQ(r.flags, kFlagTermCharSet);
  EXPECT_EQ(r.term_char, '\n');

  const RpcCall g = DecodeRpcCall(Hex(kGetPortCall));
  EXPECT_EQ(g.program, kPortmapperProgram);
  EXPECT_EQ(g.procedure, kPmapProcGetPort);
  const PortMapping m = DecodePortMapping(g.args);
  EXPECT_EQ(m.program, kCoreProgram);
  EXPECT_EQ(m.version, 1u);
  EXPECT_EQ(m.protocol, kIpProtoTcp);
}

TEST(Vxi11Rpc, EncodesCallsAsPyvisaDoes) {
  RpcCall c;
  c.xid = 0x1234;
  c.program = kCoreProgram;
  c.version = 1;
  c.procedure = kCreateLink;
  c.args = EncodeCreateLinkParms({42, false, 0, "inst0"});
  EXPECT_EQ(EncodeRpcCall(c), Hex(kCreateLinkCall));
  c.xid = 0x1236;
  c.procedure = kDeviceRead;
  c.args = EncodeDeviceReadParms({1, 1024, 5000, 0, kFlagTermCharSet, '\n'});
  EXPECT_EQ(EncodeRpcCall(c), Hex(kReadCall));
}

TEST(Vxi11Rpc, ReplyHeadersMatchRpcPy) {
  // rpc.Packer.pack_replyheader(0x1236, AUTH_NONE): xid, REPLY, MSG_ACCEPTED, verf, SUCCESS.
  EXPECT_EQ(EncodeAcceptedReply(0x1236, kSuccess),
            Hex("000012360000000100000000000000000000000000000000"));
  EXPECT_EQ(EncodeAcceptedReply(9, kGarbageArgs),
            Hex("000000090000000100000000000000000000000000000004"));
  EXPECT_EQ(EncodeProgMismatchReply(9, 1, 1),
            Hex("00000009000000010000000000000000000000000000000200000001"
                "00000001"));
  // MSG_DENIED, RPC_MISMATCH, low 2, high 2.
  EXPECT_EQ(EncodeRpcMismatchReply(9), Hex("00000009000000010000000100000000"
                                           "0000000200000002"));
  const RpcReply r = DecodeRpcReply(EncodeAcceptedReply(5, kSuccess, EncodeDeviceError(4)));
  EXPECT_EQ(r.xid, 5u);
  EXPECT_TRUE(r.accepted);
  EXPECT_EQ(r.stat, 0u);
  EXPECT_EQ(DecodeDeviceError(r.results), kInvalidLinkId);
}

TEST(Vxi11Rpc, MalformedCallsThrowButKeepTheXid) {
  std::optional<uint32_t> xid;
  EXPECT_THROW(DecodeRpcCall(Hex("0000"), &xid), Vxi11DecodeError);
  EXPECT_FALSE(xid);
  EXPECT_THROW(DecodeRpcCall(Hex("0000001a0000"), &xid), Vxi11DecodeError);
  EXPECT_EQ(xid, 0x1au);
  // msg_type REPLY where a CALL is expected.
  EXPECT_THROW(DecodeRpcCall(Hex("0000001b00000001")), Vxi11DecodeError);
  // Credentials longer than 400 bytes.
  std::string call = Hex(kCreateLinkCall).substr(0, 24) + Hex("00000001000001a0");
  EXPECT_THROW(DecodeRpcCall(call), Vxi11DecodeError);
}

TEST(Vxi11Results, EncodingsAreByteExact) {
  EXPECT_EQ(EncodeCreateLinkResp({0, 1, 1024, 1u << 20}), Hex("00000000000000010000040000100000"));
  EXPECT_EQ(EncodeDeviceWriteResp({0, 6}), Hex("0000000000000006"));
  // "AB\n" with reason END: length 3, one pad byte.
  EXPECT_EQ(EncodeDeviceReadResp({0, kReasonEnd, "AB\n"}), Hex("00000000000000040000000341420a00"));
  EXPECT_EQ(EncodeDeviceReadStbResp({0, 0x10}), Hex("0000000000000010"));
  EXPECT_EQ(EncodeDeviceError(kDeviceLocked), Hex("0000000b"));
  const DeviceReadResp r = DecodeDeviceReadResp(Hex("00000000000000040000000341420a00"));
  EXPECT_EQ(r.reason, kReasonEnd);
  EXPECT_EQ(r.data, "AB\n");
}

TEST(Vxi11RecordMarking, ReassemblesFragmentsFedByteByByte) {
  EXPECT_EQ(RecordMark("abcd"), Hex("8000000461626364"));
  // Two records, the first in two fragments (first not last).
  const std::string stream = Hex("00000002"
                                 "6162"
                                 "80000001"
                                 "63") +
                             RecordMark("xyz");
  RecordAssembler a(64);
  std::vector<std::string> got;
  for (char c : stream) {
    a.Feed(std::string(1, c));
    while (auto rec = a.Next()) got.push_back(*rec);
  }
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0], "abc");
  EXPECT_EQ(got[1], "xyz");
  EXPECT_EQ(a.buffered(), 0u);
}

TEST(Vxi11RecordMarking, OversizedRecordThrows) {
  RecordAssembler a(16);
  EXPECT_THROW(a.Feed(Hex("80000011")), Vxi11DecodeError);
  RecordAssembler b(16);
  b.Feed(Hex("0000000a") + std::string(10, 'x'));  // 10 bytes so far, not last
  EXPECT_THROW(b.Feed(Hex("8000000a")), Vxi11DecodeError);
}

}  // namespace
}  // namespace msmcal::sim::vxi11
