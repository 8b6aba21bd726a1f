#pragma once
// The VXI-11 side of a Mock33520B, without sockets: one RPC call record in, one reply record out.
// It keeps the links (create_link .. destroy_link), each with its own input buffer and reply
// queue, the device lock, and the portmapper's answers; the SCPI bytes go to the same
// Mock33520B that the raw socket serves (one instrument, both wires).
//
// Semantics (VXI-11 rev. 1.0, B.6), where the mock simplifies:
// - device_write: data accumulates on the link; every '\n' outside quoted strings and
//   definite-length blocks ends a program message, and the END flag (0x08) ends one too.
//   Each message's reply (with its '\n') joins the link's reply queue.
// - device_read: up to requestSize bytes of the oldest reply, stopping after term_char when
//   flag 0x80 is set; reason END (0x04) when the reply's last byte is returned, CHR (0x02) at
//   the term char, REQCNT (0x01) when requestSize is reached. With no reply queued it answers
//   error 15 (I/O timeout) at once: the mock executes every message when it arrives, so no
//   reply can appear while waiting.
// - A lock held by another link makes write/read/trigger/clear/readstb/lock answer 11 at once
//   (no waiting for lock_timeout). Interrupt channels (SRQ) and docmd are not supported (8).
// - The links of a connection are destroyed when it closes (as the instrument does).
// Thread safety: none; the server calls it from its one I/O thread.

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "mocks/generator/mock_33520b.h"
#include "mocks/generator/scpi_parser.h"
#include "mocks/generator/vxi11_protocol.h"

namespace msmcal::sim {

// Which listening socket a call arrived on (each serves its own RPC program).
enum class Vxi11Channel { kPortmapper, kCore, kAbort };

struct Vxi11DeviceOptions {
  uint32_t core_port = 0;   // what GETPORT answers for DEVICE_CORE over TCP
  uint32_t abort_port = 0;  // create_link's abortPort and GETPORT for DEVICE_ASYNC
  uint32_t max_recv_size = vxi11::kMaxWriteBytes;
  size_t max_message_bytes = 36u << 20;  // input buffer of a link (as ServerLimits)
};

struct Vxi11Stats {
  uint64_t calls = 0;
  uint64_t garbage = 0;        // calls answered GARBAGE_ARGS or not answered
  uint64_t links_created = 0;  // successful create_link
  uint64_t messages = 0;       // program messages handed to the unit
};

class Vxi11Device {
 public:
  Vxi11Device(Mock33520B& unit, Vxi11DeviceOptions options);

  void SetPorts(uint32_t core_port, uint32_t abort_port);
  // One call record (without record marking) from `connection` (any number that tells the
  // server's connections apart). Returns the reply record, or nullopt when the record is too
  // short to carry an xid (nothing can be answered).
  std::optional<std::string> Handle(Vxi11Channel channel, std::string_view record,
                                    uint64_t connection);
  // Destroys the links created over `connection` (releasing a lock they held).
  void ConnectionClosed(uint64_t connection);

  size_t LinkCount() const { return links_.size(); }
  const Vxi11Stats& stats() const { return stats_; }

 private:
  struct Link {
    uint64_t connection = 0;
    std::string input;  // bytes of the program message being received
    MessageFramer framer;
    bool discarding = false;  // the current message overran the input buffer
    std::deque<std::string> replies;
    size_t reply_offset = 0;  // bytes of replies.front() already read
  };

  std::string Portmapper(const vxi11::RpcCall& call);
  std::string Core(const vxi11::RpcCall& call, uint64_t connection);
  std::string Abort(const vxi11::RpcCall& call);
  // nullptr when link_id is unknown.
  Link* Find(int32_t link_id);
  bool LockedByOther(int32_t link_id) const { return lock_owner_ && *lock_owner_ != link_id; }
  std::string CreateLink(const vxi11::CreateLinkParms& p, uint64_t connection);
  std::string Write(const vxi11::DeviceWriteParms& p);
  std::string Read(const vxi11::DeviceReadParms& p);
  void Execute(Link& link, std::string message);
  void Destroy(int32_t link_id);

  Mock33520B& unit_;
  Vxi11DeviceOptions options_;
  std::map<int32_t, Link> links_;
  int32_t next_link_id_ = 1;
  std::optional<int32_t> lock_owner_;
  Vxi11Stats stats_;
};

}  // namespace msmcal::sim
