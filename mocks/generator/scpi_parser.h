#pragma once
// SCPI-99 program-message parsing for the mock instrument (the instrument's side of the wire,
// written independently of the driver's client). Pure functions, no I/O.
//
// Covers: compound messages with ';' and the path rules (a header without a leading ':' continues
// from the previous header's parent node; common commands '*XXX' leave the path alone), short and
// long mnemonics case-insensitively, optional nodes, numeric suffixes, parameters separated by
// ',' (strings in quotes, definite-length blocks whose bytes may hold ';' ',' '"' or '\n').

#include <cstddef>
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

// Header pattern, e.g. "[SOURce#:]FREQuency" or "OUTPut#[:STATe]": nodes separated by ':',
// optional nodes in brackets, upper-case letters are the short form, '#' admits a numeric suffix.
// On a match returns the numeric suffix of each '#' node in order (1 when omitted).
std::optional<std::vector<int>> MatchHeader(std::string_view pattern,
                                            const std::vector<std::string>& nodes);

// Finds the end of one complete program message in `buffer` (the index of its '\n', skipping
// '\n' bytes inside quoted strings and definite-length blocks). std::nullopt while incomplete.
// A block header that cannot be parsed ends the message at the next '\n'.
std::optional<size_t> FindMessageEnd(std::string_view buffer);

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
