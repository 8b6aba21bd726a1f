#include "common/csv_writer.h"

#include <charconv>

#include "common/text_io.h"

namespace msmcal::common {

void AppendCsvCell(std::string* out, double value) { AppendShortestDouble(out, value); }

void AppendCsvCell(std::string* out, long long value) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof(buf), value);
  out->append(buf, r.ptr);
}

void AppendCsvCell(std::string* out, unsigned long long value) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof(buf), value);
  out->append(buf, r.ptr);
}

void AppendCsvCell(std::string* out, std::string_view text) { out->append(text); }

}  // namespace msmcal::common
