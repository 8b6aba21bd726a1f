#include "drivers/scpi/scpi_text.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace msmcal::scpi {

std::string FormatNumber(double value) {
  if (!std::isfinite(value)) throw std::invalid_argument("FormatNumber: value is not finite");
  char buf[64];
  for (int precision = 6; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, value);
    if (std::strtod(buf, nullptr) == value) break;
  }
  return buf;
}

std::string FormatDefiniteBlock(std::string_view payload) {
  const std::string len = std::to_string(payload.size());
  if (len.size() > 9) throw std::invalid_argument("FormatDefiniteBlock: payload too large");
  std::string out = "#" + std::to_string(len.size()) + len;
  out.append(payload);
  return out;
}

std::string Int16Payload(const std::vector<int16_t>& samples, bool big_endian) {
  std::string out(samples.size() * 2, '\0');
  for (size_t i = 0; i < samples.size(); ++i) {
    const auto u = static_cast<uint16_t>(samples[i]);
    const char hi = static_cast<char>(u >> 8), lo = static_cast<char>(u & 0xFF);
    out[2 * i] = big_endian ? hi : lo;
    out[2 * i + 1] = big_endian ? lo : hi;
  }
  return out;
}

std::optional<BlockHeader> ParseBlockHeader(std::string_view data) {
  if (data.empty()) return std::nullopt;
  if (data[0] != '#') throw std::invalid_argument("block does not start with '#'");
  if (data.size() < 2) return std::nullopt;
  if (data[1] < '1' || data[1] > '9') {
    throw std::invalid_argument("block length digit count must be 1..9, got '" +
                                std::string(1, data[1]) + "'");
  }
  const size_t n = static_cast<size_t>(data[1] - '0');
  if (data.size() < 2 + n) return std::nullopt;
  size_t len = 0;
  for (size_t i = 0; i < n; ++i) {
    const char c = data[2 + i];
    if (c < '0' || c > '9') throw std::invalid_argument("block length has a non-digit");
    len = len * 10 + static_cast<size_t>(c - '0');
  }
  return BlockHeader{2 + n, len};
}

std::string_view Trim(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t' || text.front() == '\r' ||
                           text.front() == '\n')) {
    text.remove_prefix(1);
  }
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t' || text.back() == '\r' ||
                           text.back() == '\n')) {
    text.remove_suffix(1);
  }
  return text;
}

ErrorEntry ParseErrorEntry(std::string_view reply) {
  reply = Trim(reply);
  const size_t comma = reply.find(',');
  if (comma == std::string_view::npos) {
    throw std::invalid_argument("error entry without a comma: '" + std::string(reply) + "'");
  }
  ErrorEntry e;
  std::string_view num = Trim(reply.substr(0, comma));
  if (!num.empty() && num.front() == '+') num.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(num.data(), num.data() + num.size(), e.code);
  if (ec != std::errc() || ptr != num.data() + num.size()) {
    throw std::invalid_argument("error entry with a bad code: '" + std::string(reply) + "'");
  }
  std::string_view msg = Trim(reply.substr(comma + 1));
  if (msg.size() < 2 || msg.front() != '"' || msg.back() != '"') {
    throw std::invalid_argument("error entry with an unquoted message: '" + std::string(reply) +
                                "'");
  }
  e.message = std::string(msg.substr(1, msg.size() - 2));
  return e;
}

Identity ParseIdentity(std::string_view reply) {
  reply = Trim(reply);
  std::vector<std::string> fields;
  size_t start = 0;
  for (;;) {
    const size_t comma = reply.find(',', start);
    fields.emplace_back(Trim(reply.substr(start, comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  if (fields.size() != 4) {
    throw std::invalid_argument("*IDN? reply must have 4 comma-separated fields, got " +
                                std::to_string(fields.size()) + ": '" + std::string(reply) + "'");
  }
  return Identity{fields[0], fields[1], fields[2], fields[3]};
}

double ParseNumber(std::string_view reply) {
  const std::string text(Trim(reply));
  if (text.empty()) throw std::invalid_argument("empty numeric reply");
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size()) {
    throw std::invalid_argument("not a number: '" + text + "'");
  }
  return v;
}

bool ParseBool(std::string_view reply) {
  const std::string_view t = Trim(reply);
  if (t == "1" || t == "ON" || t == "+1") return true;
  if (t == "0" || t == "OFF" || t == "+0") return false;
  throw std::invalid_argument("not a boolean: '" + std::string(t) + "'");
}

std::vector<std::string> SplitResponses(std::string_view reply) {
  std::vector<std::string> out;
  std::string cur;
  bool quoted = false;
  for (char c : reply) {
    if (c == '"') quoted = !quoted;
    if (c == ';' && !quoted) {
      out.emplace_back(Trim(cur));
      cur.clear();
    } else {
      cur.push_back(c);
    }
  }
  out.emplace_back(Trim(cur));
  return out;
}

bool IsPrintable(std::string_view text) {
  for (unsigned char c : text) {
    if ((c < 0x20 || c > 0x7E) && c != '\t') return false;
  }
  return true;
}

}  // namespace msmcal::scpi
