#pragma once
// SCPI text and byte formats, pure functions with no I/O (SCPI-99 / IEEE 488.2 conventions as the
// Keysight 33500 series uses them). Tested without a socket.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace msmcal::scpi {

// A number as a program-data token: shortest round-trip decimal ("1000", "0.25", "1.5e-07").
std::string FormatNumber(double value);

// IEEE 488.2 definite-length arbitrary block: "#<n><len><payload>", n = digits of len (1..9).
std::string FormatDefiniteBlock(std::string_view payload);

// int16 samples as a block payload in the given byte order (the order set by FORMat:BORDer:
// NORMal = big-endian, SWAPped = little-endian).
std::string Int16Payload(const std::vector<int16_t>& samples, bool big_endian);

// Header of a definite-length block at the start of `data`: on success the header size and the
// payload length; std::nullopt while `data` is too short to tell; throws std::invalid_argument
// when `data` cannot start a block ("#0" indefinite blocks are refused too).
struct BlockHeader {
  size_t header_size = 0;
  size_t payload_size = 0;
};
std::optional<BlockHeader> ParseBlockHeader(std::string_view data);

// One SYSTem:ERRor? entry: `+0,"No error"`, `-113,"Undefined header"`. Throws
// std::invalid_argument on anything else.
struct ErrorEntry {
  int code = 0;
  std::string message;
};
ErrorEntry ParseErrorEntry(std::string_view reply);

// *IDN? reply: four comma-separated fields.
struct Identity {
  std::string manufacturer;
  std::string model;
  std::string serial;
  std::string firmware;
};
Identity ParseIdentity(std::string_view reply);  // throws std::invalid_argument

// Numeric reply ("+1.0000000000000E+03", "1e3", "+100"); throws std::invalid_argument.
double ParseNumber(std::string_view reply);
// Boolean reply ("1"/"0", "ON"/"OFF"); throws std::invalid_argument.
bool ParseBool(std::string_view reply);

// Splits a response message into its units at top-level ';' (not inside quotes).
std::vector<std::string> SplitResponses(std::string_view reply);

// True when every byte is printable ASCII (0x20..0x7E) or a tab: a reply line with anything
// else is garbage on the wire.
bool IsPrintable(std::string_view text);

// Trims spaces, tabs and CR at both ends.
std::string_view Trim(std::string_view text);

}  // namespace msmcal::scpi
