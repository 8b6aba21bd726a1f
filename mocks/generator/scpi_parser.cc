#include "mocks/generator/scpi_parser.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace msmcal::sim {
namespace {

std::string_view TrimWs(std::string_view t) {
  while (!t.empty() && std::isspace(static_cast<unsigned char>(t.front()))) t.remove_prefix(1);
  while (!t.empty() && std::isspace(static_cast<unsigned char>(t.back()))) t.remove_suffix(1);
  return t;
}

// Length of a definite-length block starting at text[i] == '#' followed by a digit 1..9:
// >0 total size, 0 when incomplete, -1 when malformed.
long BlockSize(std::string_view text, size_t i) {
  if (i + 1 >= text.size()) return 0;
  const char d = text[i + 1];
  if (d < '1' || d > '9') return -1;
  const size_t n = static_cast<size_t>(d - '0');
  if (i + 2 + n > text.size()) return 0;
  size_t len = 0;
  for (size_t k = 0; k < n; ++k) {
    const char c = text[i + 2 + k];
    if (c < '0' || c > '9') return -1;
    len = len * 10 + static_cast<size_t>(c - '0');
  }
  const size_t total = 2 + n + len;
  if (i + total > text.size()) return 0;
  return static_cast<long>(total);
}

bool IsBlockStart(std::string_view text, size_t i) {
  return text[i] == '#' && i + 1 < text.size() &&
         std::isdigit(static_cast<unsigned char>(text[i + 1]));
}

// TrimWs that never trims into a definite-length block: a block's last bytes are data even when
// they are whitespace (an int16 sample 0x200A ends in ' ', '\n').
std::string_view TrimWsOutsideBlocks(std::string_view t) {
  while (!t.empty() && std::isspace(static_cast<unsigned char>(t.front()))) t.remove_prefix(1);
  size_t keep = 0;  // the end of the last complete block
  bool quoted = false;
  char quote = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    const char c = t[i];
    if (quoted) {
      if (c == quote) quoted = false;
      continue;
    }
    if (c == '"' || c == '\'') {
      quoted = true;
      quote = c;
    } else if (IsBlockStart(t, i)) {
      const long size = BlockSize(t, i);
      if (size > 0) {
        i += static_cast<size_t>(size) - 1;
        keep = i + 1;
      }
    }
  }
  while (t.size() > keep && std::isspace(static_cast<unsigned char>(t.back()))) t.remove_suffix(1);
  return t;
}

}  // namespace

std::string Upper(std::string_view text) {
  std::string out(text);
  for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

bool MatchMnemonic(std::string_view pattern, std::string_view text) {
  std::string short_form;
  for (char c : pattern) {
    if (std::isupper(static_cast<unsigned char>(c))) short_form.push_back(c);
  }
  const std::string t = Upper(text);
  return t == short_form || t == Upper(pattern);
}

SplitResult SplitProgramMessage(std::string_view message) {
  SplitResult result;
  std::vector<std::string_view> pieces;
  size_t start = 0;
  bool quoted = false;
  char quote = 0;
  for (size_t i = 0; i < message.size(); ++i) {
    const char c = message[i];
    if (quoted) {
      if (c == quote) quoted = false;
      continue;
    }
    if (c == '"' || c == '\'') {
      quoted = true;
      quote = c;
    } else if (IsBlockStart(message, i)) {
      const long size = BlockSize(message, i);
      if (size <= 0) {
        pieces.push_back(message.substr(start, i - start));
        result.failure = ParseFailure{-161, "Invalid block data"};
        break;
      }
      i += static_cast<size_t>(size) - 1;
    } else if (c == ';') {
      pieces.push_back(message.substr(start, i - start));
      start = i + 1;
    }
  }
  if (!result.failure) pieces.push_back(message.substr(start));

  for (size_t p = 0; p < pieces.size(); ++p) {
    std::string_view unit_text = TrimWsOutsideBlocks(pieces[p]);
    if (unit_text.empty()) {
      if (p + 1 == pieces.size() && p > 0) break;  // trailing ';'
      if (!result.failure) result.failure = ParseFailure{-102, "Syntax error"};
      break;
    }
    if (result.failure && p + 1 == pieces.size()) break;  // the unit holding the bad block
    size_t h = 0;
    while (h < unit_text.size() && !std::isspace(static_cast<unsigned char>(unit_text[h]))) ++h;
    std::string_view header = unit_text.substr(0, h);
    std::string_view rest = TrimWsOutsideBlocks(unit_text.substr(h));
    CommandUnit unit;
    if (header.front() == ':') {
      unit.absolute = true;
      header.remove_prefix(1);
    }
    if (!header.empty() && header.back() == '?') {
      unit.query = true;
      header.remove_suffix(1);
    }
    if (!header.empty() && header.front() == '*') unit.common = true;
    bool ok = !header.empty();
    size_t s = 0;
    while (ok) {
      const size_t colon = header.find(':', s);
      std::string_view node = header.substr(s, colon == std::string_view::npos ? colon : colon - s);
      if (node.empty()) ok = false;
      for (size_t k = 0; ok && k < node.size(); ++k) {
        const unsigned char c = static_cast<unsigned char>(node[k]);
        ok = std::isalnum(c) || c == '_' || (c == '*' && k == 0 && unit.common);
      }
      if (ok) unit.nodes.emplace_back(node);
      if (colon == std::string_view::npos) break;
      s = colon + 1;
    }
    if (!ok) {
      result.failure = ParseFailure{-102, "Syntax error"};
      break;
    }
    // Parameters at top-level ','.
    if (!rest.empty()) {
      size_t ps = 0;
      bool q = false;
      char qc = 0;
      for (size_t i = 0; i <= rest.size(); ++i) {
        if (i < rest.size()) {
          const char c = rest[i];
          if (q) {
            if (c == qc) q = false;
            continue;
          }
          if (c == '"' || c == '\'') {
            q = true;
            qc = c;
            continue;
          }
          if (IsBlockStart(rest, i)) {
            const long size = BlockSize(rest, i);
            if (size > 0) i += static_cast<size_t>(size) - 1;
            continue;
          }
          if (c != ',') continue;
        }
        std::string_view param = TrimWsOutsideBlocks(rest.substr(ps, i - ps));
        if (param.empty()) {
          ok = false;
          break;
        }
        unit.params.emplace_back(param);
        ps = i + 1;
      }
      if (!ok) {
        result.failure = ParseFailure{-102, "Syntax error"};
        break;
      }
    }
    result.units.push_back(std::move(unit));
  }
  return result;
}

std::vector<std::string> ResolvePath(const CommandUnit& unit, std::vector<std::string>& current) {
  if (unit.common) return unit.nodes;
  std::vector<std::string> full;
  if (!unit.absolute) full = current;
  full.insert(full.end(), unit.nodes.begin(), unit.nodes.end());
  current.assign(full.begin(), full.end() - 1);
  return full;
}

std::vector<HeaderNode> SplitHeaderNodes(const std::vector<std::string>& nodes) {
  std::vector<HeaderNode> out(nodes.size());
  for (size_t i = 0; i < nodes.size(); ++i) {
    std::string_view node = nodes[i];
    size_t k = node.size();
    while (k > 0 && std::isdigit(static_cast<unsigned char>(node[k - 1]))) --k;
    HeaderNode& h = out[i];
    h.alpha = Upper(node.substr(0, k));
    h.valid = !h.alpha.empty() && node.size() - k <= 3;
    if (k < node.size() && h.valid) h.suffix = std::atoi(std::string(node.substr(k)).c_str());
  }
  return out;
}

HeaderPattern::HeaderPattern(std::string_view pattern) {
  int depth = 0;
  Node cur;
  bool started = false;
  auto flush = [&] {
    if (started) nodes_.push_back(cur);
    cur = Node{};
    started = false;
  };
  for (char c : pattern) {
    if (c == '[') {
      flush();
      ++depth;
    } else if (c == ']') {
      flush();
      --depth;
    } else if (c == ':') {
      flush();
    } else if (c == '#') {
      cur.suffix = true;
    } else {
      if (!started) cur.optional = depth > 0;
      started = true;
      cur.long_form.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(c))));
      if (std::isupper(static_cast<unsigned char>(c)) || c == '*' || c == '?') {
        cur.short_form.push_back(c);
      }
    }
  }
  flush();
}

bool HeaderPattern::MatchFrom(size_t pi, size_t ni, const std::vector<HeaderNode>& nodes,
                              std::vector<int>& suffixes, std::vector<char>& failed,
                              uint64_t* work) const {
  if (pi == nodes_.size()) return ni == nodes.size();
  // Whether (pi, ni) can reach the end does not depend on the path that led here (the suffixes
  // pushed so far are only output): a state that failed once fails again. Remembering it keeps
  // the search linear in states, (pattern nodes + 1) x (header nodes + 1); without it, runs of
  // optional nodes with the same mnemonic made it exponential (found by the fuzzer).
  char& dead = failed[pi * (nodes.size() + 1) + ni];
  if (dead) return false;
  if (work) ++*work;
  const Node& p = nodes_[pi];
  if (ni < nodes.size()) {
    const HeaderNode& h = nodes[ni];
    if (h.valid && (h.alpha == p.short_form || h.alpha == p.long_form) &&
        (h.suffix < 0 || p.suffix)) {
      if (p.suffix) suffixes.push_back(h.suffix < 0 ? 1 : h.suffix);
      if (MatchFrom(pi + 1, ni + 1, nodes, suffixes, failed, work)) return true;
      if (p.suffix) suffixes.pop_back();
    }
  }
  if (p.optional) {
    if (p.suffix) suffixes.push_back(1);
    if (MatchFrom(pi + 1, ni, nodes, suffixes, failed, work)) return true;
    if (p.suffix) suffixes.pop_back();
  }
  dead = 1;
  return false;
}

std::optional<std::vector<int>> HeaderPattern::Match(const std::vector<HeaderNode>& nodes,
                                                     uint64_t* work) const {
  if (nodes.size() > nodes_.size()) return std::nullopt;
  std::vector<int> suffixes;
  std::vector<char> failed((nodes_.size() + 1) * (nodes.size() + 1), 0);
  if (MatchFrom(0, 0, nodes, suffixes, failed, work)) return suffixes;
  return std::nullopt;
}

std::optional<std::vector<int>> MatchHeader(std::string_view pattern,
                                            const std::vector<std::string>& nodes) {
  return HeaderPattern(pattern).Match(SplitHeaderNodes(nodes));
}

std::optional<size_t> FindMessageEnd(std::string_view buffer) {
  bool quoted = false;
  char quote = 0;
  for (size_t i = 0; i < buffer.size(); ++i) {
    const char c = buffer[i];
    if (quoted) {
      if (c == quote) quoted = false;
      if (c == '\n') return i;  // an unterminated string ends at the line end
      continue;
    }
    if (c == '"' || c == '\'') {
      quoted = true;
      quote = c;
    } else if (IsBlockStart(buffer, i)) {
      const long size = BlockSize(buffer, i);
      if (size == 0) return std::nullopt;  // wait for the rest of the block
      if (size > 0) i += static_cast<size_t>(size) - 1;
    } else if (c == '\n') {
      return i;
    }
  }
  return std::nullopt;
}

std::optional<size_t> MessageFramer::Next(std::string_view buffer) {
  while (pos_ < buffer.size()) {
    if (block_left_ > 0) {
      const uint64_t take = std::min<uint64_t>(block_left_, buffer.size() - pos_);
      pos_ += static_cast<size_t>(take);
      block_left_ -= take;
      continue;
    }
    const char c = buffer[pos_];
    if (quoted_) {
      if (c == quote_) quoted_ = false;
      if (c == '\n') {  // an unterminated string ends at the line end
        quoted_ = false;
        return pos_++;
      }
      ++pos_;
      continue;
    }
    if (c == '#' && pos_ + 1 == buffer.size()) return std::nullopt;  // a block may follow
    if (c == '"' || c == '\'') {
      quoted_ = true;
      quote_ = c;
    } else if (IsBlockStart(buffer, pos_)) {
      // "#<n><n digits>": wait until the header is complete, then skip the payload as it comes.
      const size_t n = static_cast<size_t>(buffer[pos_ + 1] - '0');
      if (n >= 1) {
        if (pos_ + 2 + n > buffer.size()) return std::nullopt;
        uint64_t len = 0;
        bool digits = true;
        for (size_t k = 0; k < n && digits; ++k) {
          const char d = buffer[pos_ + 2 + k];
          digits = d >= '0' && d <= '9';
          len = len * 10 + static_cast<uint64_t>(d - '0');
        }
        if (digits) {
          pos_ += 2 + n;
          block_left_ = len;
          continue;
        }
      }
    } else if (c == '\n') {
      return pos_++;
    }
    ++pos_;
  }
  return std::nullopt;
}

void MessageFramer::Reset(size_t start) {
  pos_ = start;
  quoted_ = false;
  block_left_ = 0;
}

void MessageFramer::Shift(size_t n) { pos_ -= std::min(n, pos_); }

std::optional<double> ParseNumericWithUnit(std::string_view text, std::string_view unit) {
  const std::string s(TrimWs(text));
  if (s.empty()) return std::nullopt;
  const char* begin = s.c_str();
  char* end = nullptr;
  // Reject hex/inf/nan spellings that strtod accepts but SCPI does not.
  for (char c : s) {
    if (c == 'x' || c == 'X') return std::nullopt;
  }
  if (std::isalpha(static_cast<unsigned char>(s[0]))) return std::nullopt;
  const double v = std::strtod(begin, &end);
  if (end == begin || !std::isfinite(v)) return std::nullopt;
  const std::string suffix = Upper(TrimWs(std::string_view(end)));
  if (suffix.empty()) return v;
  // Alternatives separated by '|'.
  size_t a = 0;
  while (a <= unit.size()) {
    const size_t bar = unit.find('|', a);
    const std::string u = Upper(unit.substr(a, bar == std::string_view::npos ? bar : bar - a));
    if (!u.empty() && suffix.size() >= u.size() &&
        suffix.compare(suffix.size() - u.size(), u.size(), u) == 0) {
      const std::string prefix = suffix.substr(0, suffix.size() - u.size());
      if (prefix.empty()) return v;
      if (prefix == "M") return (u == "HZ" || u == "OHM") ? v * 1e6 : v * 1e-3;
      if (prefix == "MA") return v * 1e6;
      if (prefix == "K") return v * 1e3;
      if (prefix == "U") return v * 1e-6;
      if (prefix == "N") return v * 1e-9;
      if (prefix == "G") return v * 1e9;
    }
    if (bar == std::string_view::npos) break;
    a = bar + 1;
  }
  return std::nullopt;
}

std::optional<bool> ParseBoolean(std::string_view text) {
  const std::string t = Upper(TrimWs(text));
  if (t == "ON") return true;
  if (t == "OFF") return false;
  if (auto v = ParseNumericWithUnit(t, "")) return std::lround(*v) != 0;
  return std::nullopt;
}

std::string FormatReplyNumber(double value) {
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%+.13E", value);
  return buf;
}

}  // namespace msmcal::sim
