// The VXI-11 server on loopback sockets: the portmapper over TCP and UDP (on a free port, not
// 111), the core channel, a stream the server cannot resynchronise, and the fallback message when
// the portmapper port cannot be bound.
#include "mocks/generator/vxi11_server.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <string>

#include "mocks/generator/mock_server.h"
#include "mocks/generator/vxi11_protocol.h"

namespace msmcal::sim {
namespace {

using namespace vxi11;

class Socket {
 public:
  Socket(int type, int port) : fd_(socket(AF_INET, type, 0)) {
    timeval tv{20, 0};  // failure bound only: every read ends on a reply
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0;
  }
  ~Socket() { close(fd_); }
  bool connected() const { return connected_; }
  void Send(const std::string& bytes) {
    ASSERT_EQ(send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL),
              static_cast<ssize_t>(bytes.size()));
  }
  // One datagram (UDP), or whatever arrives (TCP); empty on EOF or timeout.
  std::string Receive() {
    char buf[65536];
    const ssize_t n = recv(fd_, buf, sizeof(buf), 0);
    return n > 0 ? std::string(buf, static_cast<size_t>(n)) : std::string();
  }
  // One TCP record.
  std::string Record() {
    RecordAssembler a(1 << 20);
    for (;;) {
      if (auto r = a.Next()) return *r;
      const std::string bytes = Receive();
      if (bytes.empty()) return "";
      a.Feed(bytes);
    }
  }

 private:
  int fd_;
  bool connected_ = false;
};

std::string Call(uint32_t xid, uint32_t prog, uint32_t vers, uint32_t proc,
                 const std::string& args) {
  RpcCall c;
  c.xid = xid;
  c.program = prog;
  c.version = vers;
  c.procedure = proc;
  c.args = args;
  return EncodeRpcCall(c);
}

TEST(Vxi11Server, PortmapperCoreAndBadStreams) {
  Mock33520B unit(UnitOptions{}, nullptr);
  Vxi11ServerOptions o;
  o.portmapper_port = 0;
  Vxi11Server server(unit, o);
  server.Start();
  ASSERT_GT(server.portmapper_port(), 0);
  XdrWriter core_port;
  core_port.PutUint(static_cast<uint32_t>(server.core_port()));
  const std::string getport =
      Call(7, kPortmapperProgram, 2, kPmapProcGetPort, EncodePortMapping({kCoreProgram, 1, 6, 0}));
  {
    Socket tcp(SOCK_STREAM, server.portmapper_port());
    ASSERT_TRUE(tcp.connected());
    tcp.Send(RecordMark(getport));
    EXPECT_EQ(tcp.Record(), EncodeAcceptedReply(7, kSuccess, core_port.bytes()));
  }
  {
    Socket udp(SOCK_DGRAM, server.portmapper_port());
    udp.Send(getport);
    EXPECT_EQ(udp.Receive(), EncodeAcceptedReply(7, kSuccess, core_port.bytes()));
  }
  {
    // A record over the bound cannot be skipped: that connection is closed...
    Socket bad(SOCK_STREAM, server.core_port());
    bad.Send(std::string("\xff\xff\xff\xff", 4));
    EXPECT_EQ(bad.Receive(), "");
  }
  // ...and the server serves the next one.
  Socket s(SOCK_STREAM, server.core_port());
  s.Send(
      RecordMark(Call(1, kCoreProgram, 1, kCreateLink, EncodeCreateLinkParms({1, 0, 0, "inst0"}))));
  const CreateLinkResp link = DecodeCreateLinkResp(DecodeRpcReply(s.Record()).results);
  EXPECT_EQ(link.error, kNoError);
  EXPECT_EQ(link.abort_port, static_cast<uint32_t>(server.abort_port()));
  s.Send(RecordMark(Call(2, kCoreProgram, 1, kDeviceWrite,
                         EncodeDeviceWriteParms({link.link_id, 1000, 0, kFlagEnd, "*IDN?\n"}))));
  EXPECT_EQ(s.Record(), EncodeAcceptedReply(2, kSuccess, EncodeDeviceWriteResp({0, 6})));
  s.Send(RecordMark(Call(3, kCoreProgram, 1, kDeviceRead,
                         EncodeDeviceReadParms({link.link_id, 4096, 1000, 0, 0, 0}))));
  EXPECT_EQ(s.Record(),
            EncodeAcceptedReply(
                3, kSuccess, EncodeDeviceReadResp({0, kReasonEnd, UnitOptions{}.identity + "\n"})));
  server.Stop();
}

TEST(Vxi11Server, PortmapperPortTakenServesCoreAlone) {
  Mock33520B unit(UnitOptions{}, nullptr);
  MockGeneratorServer holder(unit, 0);  // holds a port the portmapper then cannot bind
  holder.Start();
  Vxi11ServerOptions o;
  o.portmapper_port = holder.port();
  Vxi11Server server(unit, o);
  server.Start();
  EXPECT_EQ(server.portmapper_port(), -1);
  EXPECT_NE(server.portmapper_error().find("needs port 111"), std::string::npos)
      << server.portmapper_error();
  EXPECT_NE(server.portmapper_error().find(std::to_string(server.core_port())), std::string::npos);
  Socket s(SOCK_STREAM, server.core_port());
  EXPECT_TRUE(s.connected());
}

}  // namespace
}  // namespace msmcal::sim
