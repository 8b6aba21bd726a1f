#pragma once
// SCPI-99 program-message parsing for the mock instrument (the instrument's side of the wire,
// written independently of the driver's client). Pure functions, no I/O.
//
// Covers: compound messages with ';' and the path rules (a header without a leading ':' continues
// from the previous header's parent node; common commands '*XXX' leave the path alone), short and
// long mnemonics case-insensitively, optional nodes, numeric suffixes, parameters separated by
// ',' (strings in quotes, definite-length blocks whose bytes may hold ';' ',' '"' or '\n').

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace msmcal::sim {

// One program message unit: header nodes (as typed) and raw parameter texts (trimmed; a block
// parameter keeps its "#<n><len>" header and payload).
struct CommandUnit {
  bool absolute = false;           // header started with ':'
  bool common = false;             // '*IDN?' style
  bool query = false;              // header ended with '?'
  std::vector<std::string> nodes;  // e.g. {"SOUR1", "FREQ"} (for common: {"*IDN"})
  std::vector<std::string> params;
};

// Splits one program message (without its '\n') into units at top-level ';' and parses each
// header. Throws std::invalid_argument for a malformed block ("-161") or header ("-102").
struct ParseFailure {
  int code = 0;
  std::string message;
};
struct SplitResult {
  std::vector<CommandUnit> units;
  std::optional<ParseFailure> failure;  // parsing stopped at the failing unit
};
SplitResult SplitProgramMessage(std::string_view message);

// Applies the SCPI path rule: returns the full node list of `unit` given the previous unit's
// full node list (updated in place to the new current path).
std::vector<std::string> ResolvePath(const CommandUnit& unit, std::vector<std::string>& current);

// One received header node split into its mnemonic (upper case) and numeric suffix (-1 when
// absent); `valid` is false for a node no pattern can match (no letters, suffix over 3 digits).
struct HeaderNode {
  std::string alpha;
  int suffix = -1;
  bool valid = false;
};
std::vector<HeaderNode> SplitHeaderNodes(const std::vector<std::string>& nodes);

// Header pattern, e.g. "[SOURce#:]FREQuency" or "OUTPut#[:STATe]": nodes separated by ':',
// optional nodes in brackets, upper-case letters are the short form, '#' admits a numeric suffix.
// Compiled once; Match() allocates its result and a table of the states it ruled out (linear in
// pattern nodes x header nodes, whatever the pattern).
class HeaderPattern {
 public:
  explicit HeaderPattern(std::string_view pattern);
  // On a match returns the numeric suffix of each '#' node in order (1 when omitted). Adds the
  // node comparisons it made to *work when work is not null (a cost measure for tests).
  std::optional<std::vector<int>> Match(const std::vector<HeaderNode>& nodes,
                                        uint64_t* work = nullptr) const;
  // Most nodes a matching header can have (every optional node present).
  size_t max_nodes() const { return nodes_.size(); }

 private:
  struct Node {
    std::string long_form;  // upper case
    std::string short_form;
    bool optional = false;
    bool suffix = false;
  };
  bool MatchFrom(size_t pi, size_t ni, const std::vector<HeaderNode>& nodes,
                 std::vector<int>& suffixes, std::vector<char>& failed, uint64_t* work) const;
  std::vector<Node> nodes_;
};

// Convenience form of HeaderPattern(pattern).Match(SplitHeaderNodes(nodes)).
std::optional<std::vector<int>> MatchHeader(std::string_view pattern,
                                            const std::vector<std::string>& nodes);

// Finds the end of one complete program message in `buffer` (the index of its '\n', skipping
// '\n' bytes inside quoted strings and definite-length blocks). std::nullopt while incomplete.
// A block header that cannot be parsed ends the message at the next '\n'.
std::optional<size_t> FindMessageEnd(std::string_view buffer);

// The same framing over a buffer that grows at its end, in linear time: each byte is examined
// once however it arrives (only a block header split across arrivals, at most 11 bytes, is
// looked at again). Positions are indices into the caller's buffer; after the caller erases a
// prefix of n bytes it calls Shift(n).
class MessageFramer {
 public:
  // Scans the bytes of `buffer` not yet seen; returns the index of the terminating '\n' of the
  // message that started at the last Reset() (or the start), or nullopt while incomplete.
  std::optional<size_t> Next(std::string_view buffer);
  // Starts a new message at `start` (the index after the previous terminator).
  void Reset(size_t start);
  void Shift(size_t n);
  // Index of the first byte not yet scanned.
  size_t scanned() const { return pos_; }

 private:
  size_t pos_ = 0;
  bool quoted_ = false;
  char quote_ = 0;
  uint64_t block_left_ = 0;  // payload bytes of a definite-length block still to skip
};

// Numeric parameter with optional unit suffix. `unit` is the base unit (e.g. "HZ", "V", "DEG",
// "OHM", "S", "SA/S") accepted after an SI prefix (M = milli except MHZ/MOHM = mega, MA = mega,
// K, U, N, G). Returns nullopt when the text is not a number with that unit. MIN/MAX/DEF are
// handled by the caller.
std::optional<double> ParseNumericWithUnit(std::string_view text, std::string_view unit);

// ON/OFF/1/0 (and numbers: non-zero = true). nullopt otherwise.
std::optional<bool> ParseBoolean(std::string_view text);

// Upper-cased copy.
std::string Upper(std::string_view text);

// Matches a character-data parameter against a mnemonic like "SQUare" (short or long form).
bool MatchMnemonic(std::string_view pattern, std::string_view text);

// Formats a numeric reply the way the 33500 series does: "+1.0000000000000E+03".
std::string FormatReplyNumber(double value);

}  // namespace msmcal::sim
