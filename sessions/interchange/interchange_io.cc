#include "sessions/interchange/interchange_io.h"

#include <fcntl.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <atomic>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <sstream>
#include <string_view>

#include "common/csv_writer.h"
#include "common/text_io.h"
#include "common/yaml_fields.h"
#include "processing/dataset/hall_csv.h"
#include "sessions/interchange/csv_reader.h"

namespace msmcal::interchange {
namespace {

namespace fs = std::filesystem;
using dataset::BeamRole;
using dataset::Step2Kind;

constexpr const char* kHallHeader = dataset::kHallReadingsHeader;
constexpr const char* kClockHeader = dataset::kHallClockHeader;
constexpr const char* kMargFullHeader = "t_s,ax_g,ay_g,az_g,gx_dps,gy_dps,gz_dps,mx_uT,my_uT,mz_uT";
constexpr const char* kMargMagHeader = "t_s,mx_uT,my_uT,mz_uT";

// "file:line: what" (line 0: no line).
[[noreturn]] void Fail(const std::string& file, int line, const std::string& what) {
  std::string msg = file;
  if (line > 0) msg += ":" + std::to_string(line);
  msg += ": " + what;
  throw InterchangeError(msg);
}

std::string Quote(std::string_view s) { return "'" + std::string(s) + "'"; }

std::string ReadWholeFile(const fs::path& path, const std::string& display) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) Fail(display, 0, "file not found (expected a regular file)");
  std::ifstream in(path, std::ios::binary);
  if (!in) Fail(display, 0, std::string("cannot open: ") + std::strerror(errno));
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) Fail(display, 0, "read error");
  return ss.str();
}

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

// Strict number parsing: the whole text must be consumed, and the value must be finite (the
// interchange format refuses nan and inf in every spelling: "nan", "inf", ".inf", "1e999").
bool ParseDouble(std::string_view s, double* out) {
  s = Trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(s.data(), end, *out);
  return ec == std::errc() && ptr == end && std::isfinite(*out);
}

// Integers: the whole text must be an integer, or a decimal number with an integral value
// ("3", "3.0", "3e0"; every number in the format is a decimal number).
template <typename Int>
bool ParseInt(std::string_view s, Int* out) {
  s = Trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(s.data(), end, *out);
  if (ec == std::errc() && ptr == end) return true;
  double d;
  if (!ParseDouble(s, &d) || d != std::floor(d)) return false;
  if (d < static_cast<double>(std::numeric_limits<Int>::min()) ||
      d > static_cast<double>(std::numeric_limits<Int>::max()))
    return false;
  *out = static_cast<Int>(d);
  return true;
}

// Why `s` is not a number: names the non-finite case, which the format forbids explicitly.
std::string NotANumber(std::string_view s) {
  s = Trim(s);
  double v;
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(s.data() + (!s.empty() && s.front() == '+'), end, v);
  const bool non_finite = (ptr == end && ((ec == std::errc() && !std::isfinite(v)) ||
                                          ec == std::errc::result_out_of_range)) ||
                          s == ".inf" || s == "-.inf" || s == ".nan" || s == ".Inf" ||
                          s == "-.Inf" || s == ".NaN" || s == ".INF" || s == "-.INF" || s == ".NAN";
  return Quote(s) + (non_finite ? " is not a finite number (nan and inf are not allowed)"
                                : " is not a number");
}

std::string NormaliseHeader(std::string_view line) {
  std::string out;
  size_t start = 0;
  while (true) {
    size_t comma = line.find(',', start);
    if (!out.empty() || start > 0) out += ',';
    out += Trim(line.substr(start, comma - start));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  // Tolerate a UTF-8 byte-order mark written by spreadsheet tools.
  if (out.rfind("\xEF\xBB\xBF", 0) == 0) out.erase(0, 3);
  return out;
}

}  // namespace

// ------------------------------------------------------------------------------------------ CSV

CsvReader::CsvReader(const fs::path& path, std::string display,
                     const std::vector<const char*>& headers)
    : display_(std::move(display)), text_(ReadWholeFile(path, display_)) {
  ReadHeader(headers);
}

CsvReader::CsvReader(Text text, std::string display, const std::vector<const char*>& headers)
    : display_(std::move(display)), text_(std::move(text.contents)) {
  ReadHeader(headers);
}

void CsvReader::ReadHeader(const std::vector<const char*>& headers) {
  if (!NextLine()) {
    Fail(display_, 1, "empty file, expected header " + Quote(headers.front()));
  }
  const std::string got = NormaliseHeader(line_text_);
  for (size_t i = 0; i < headers.size(); ++i) {
    if (got == headers[i]) {
      header_index_ = static_cast<int>(i);
      break;
    }
  }
  if (header_index_ < 0) {
    std::string expected = Quote(headers[0]);
    for (size_t i = 1; i < headers.size(); ++i) expected += " or " + Quote(headers[i]);
    Fail(display_, line_, "header is " + Quote(got) + " but expected " + expected);
  }
  std::string_view h = headers[header_index_];
  size_t start = 0;
  while (true) {
    size_t comma = h.find(',', start);
    columns_.emplace_back(h.substr(start, comma - start));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
}

bool CsvReader::Next() {
  while (NextLine()) {
    if (Trim(line_text_).empty()) continue;
    cells_.clear();
    size_t start = 0;
    while (true) {
      size_t comma = line_text_.find(',', start);
      cells_.push_back(line_text_.substr(start, comma - start));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    if (cells_.size() != columns_.size()) {
      Fail(display_, line_,
           "expected " + std::to_string(columns_.size()) + " cells (" + Quote(HeaderText()) +
               ") but got " + std::to_string(cells_.size()));
    }
    return true;
  }
  return false;
}

double CsvReader::Double(size_t i) const {
  double v;
  if (!ParseDouble(cells_[i], &v)) {
    Fail(display_, line_, "column " + Quote(columns_[i]) + ": " + NotANumber(cells_[i]));
  }
  return v;
}

namespace {

template <typename Int>
Int CellInteger(const std::string& display, int line, const std::string& column,
                std::string_view cell) {
  Int v;
  if (!ParseInt(cell, &v)) {
    Fail(display, line,
         "column " + Quote(column) + ": " + Quote(Trim(cell)) + " is not an integer");
  }
  return v;
}

}  // namespace

int CsvReader::Int(size_t i) const {
  return CellInteger<int>(display_, line_, columns_[i], cells_[i]);
}

long long CsvReader::Int64(size_t i) const {
  return CellInteger<long long>(display_, line_, columns_[i], cells_[i]);
}

std::string CsvReader::HeaderText() const {
  std::string h;
  for (size_t i = 0; i < columns_.size(); ++i) h += (i ? "," : "") + columns_[i];
  return h;
}

bool CsvReader::NextLine() {
  if (pos_ >= text_.size()) return false;
  size_t nl = text_.find('\n', pos_);
  size_t end = nl == std::string::npos ? text_.size() : nl;
  line_text_ = std::string_view(text_).substr(pos_, end - pos_);
  if (!line_text_.empty() && line_text_.back() == '\r') line_text_.remove_suffix(1);
  pos_ = nl == std::string::npos ? text_.size() : nl + 1;
  ++line_;
  return true;
}

namespace {

std::vector<dataset::HallReading> HallReadingRows(CsvReader& csv) {
  const std::string& display = csv.display();
  std::vector<dataset::HallReading> out;
  while (csv.Next()) {
    dataset::HallReading r;
    r.mcu_time_us = csv.Double(0);
    r.bx_uT = csv.Double(1);
    r.by_uT = csv.Double(2);
    r.bz_uT = csv.Double(3);
    if (!out.empty() && r.mcu_time_us <= out.back().mcu_time_us) {
      Fail(display, csv.line(),
           "column 'mcu_time_us': readings must be in strictly increasing time, got " +
               common::ShortestDouble(r.mcu_time_us) + " after " +
               common::ShortestDouble(out.back().mcu_time_us));
    }
    out.push_back(r);
  }
  return out;
}

std::vector<double> ClockEdgeRows(CsvReader& csv) {
  const std::string& display = csv.display();
  std::vector<double> out;
  while (csv.Next()) {
    const double t = csv.Double(0);
    if (!out.empty() && t <= out.back()) {
      Fail(display, csv.line(),
           "column 'mcu_time_us': clock edges must be strictly ascending, got " +
               common::ShortestDouble(t) + " after " + common::ShortestDouble(out.back()));
    }
    out.push_back(t);
  }
  return out;
}

std::vector<dataset::HallReading> ReadHallReadings(const fs::path& path,
                                                   const std::string& display) {
  CsvReader csv(path, display, {kHallHeader});
  return HallReadingRows(csv);
}

std::vector<double> ReadClockEdges(const fs::path& path, const std::string& display) {
  CsvReader csv(path, display, {kClockHeader});
  return ClockEdgeRows(csv);
}

dataset::HallRecording ReadHall(const fs::path& readings, const std::string& readings_display,
                                const fs::path& clock, const std::string& clock_display) {
  std::error_code ec;
  const bool has_readings = fs::exists(readings, ec);
  const bool has_clock = fs::exists(clock, ec);
  if (has_readings && !has_clock) {
    Fail(clock_display, 0,
         "file not found: " + readings_display + " needs its clock edges in " + clock_display);
  }
  if (!has_readings && has_clock) {
    Fail(readings_display, 0,
         "file not found: " + clock_display + " exists without its readings " + readings_display);
  }
  dataset::HallRecording hall;
  hall.readings = ReadHallReadings(readings, readings_display);
  hall.clock_edges_us = ReadClockEdges(clock, clock_display);
  return hall;
}

dataset::MargRecording MargRows(CsvReader& csv) {
  dataset::MargRecording rec;
  rec.has_inertial = csv.header_index() == 0;
  while (csv.Next()) {
    dataset::MargSample s;
    s.t_s = csv.Double(0);
    if (rec.has_inertial) {
      s.ax_g = csv.Double(1);
      s.ay_g = csv.Double(2);
      s.az_g = csv.Double(3);
      s.gx_dps = csv.Double(4);
      s.gy_dps = csv.Double(5);
      s.gz_dps = csv.Double(6);
      s.mx_uT = csv.Double(7);
      s.my_uT = csv.Double(8);
      s.mz_uT = csv.Double(9);
    } else {
      s.mx_uT = csv.Double(1);
      s.my_uT = csv.Double(2);
      s.mz_uT = csv.Double(3);
    }
    rec.samples.push_back(s);
  }
  return rec;
}

dataset::MargRecording ReadMarg(const fs::path& path, const std::string& display) {
  CsvReader csv(path, display, {kMargFullHeader, kMargMagHeader});
  return MargRows(csv);
}

std::string FormatHallReadings(const std::vector<dataset::HallReading>& readings) {
  std::string out = std::string(kHallHeader) + "\n";
  out.reserve(out.size() + readings.size() * 48);
  for (const auto& r : readings) {
    dataset::AppendHallReadingRow(&out, r.mcu_time_us, r.bx_uT, r.by_uT, r.bz_uT);
  }
  return out;
}

std::string FormatClockEdges(const std::vector<double>& edges) {
  std::string out = std::string(kClockHeader) + "\n";
  for (double t : edges) dataset::AppendClockEdgeRow(&out, t);
  return out;
}

std::string FormatMarg(const dataset::MargRecording& rec) {
  std::string out = std::string(rec.has_inertial ? kMargFullHeader : kMargMagHeader) + "\n";
  for (const auto& s : rec.samples) {
    if (rec.has_inertial) {
      common::AppendCsvRow(&out, s.t_s, s.ax_g, s.ay_g, s.az_g, s.gx_dps, s.gy_dps, s.gz_dps,
                           s.mx_uT, s.my_uT, s.mz_uT);
    } else {
      common::AppendCsvRow(&out, s.t_s, s.mx_uT, s.my_uT, s.mz_uT);
    }
  }
  return out;
}

// ----------------------------------------------------------------------------------------- YAML

// A YAML value with its path for messages ("step2.frames[3].kind").
class YamlReader {
 public:
  explicit YamlReader(std::string display) : display_(std::move(display)) {}

  YAML::Node Load(const std::string& text) const {
    return common::YamlFields(display_, [](const std::string& m) { throw InterchangeError(m); })
        .Load(text, "YAML syntax error: ");
  }

  static int Line(const YAML::Node& node) { return common::YamlLine(node); }

  [[noreturn]] void FailAt(const YAML::Node& node, const std::string& field,
                           const std::string& what) const {
    Fail(display_, Line(node), "field " + Quote(field) + ": " + what);
  }

  void ExpectMap(const YAML::Node& node, const std::string& field) const {
    if (!node.IsMap()) FailAt(node, field, "expected a mapping");
  }

  // map[key], which must exist.
  YAML::Node Get(const YAML::Node& map, const std::string& key, const std::string& field) const {
    ExpectMap(map, field.empty() ? "(top level)" : field);
    const YAML::Node value = map[key];
    const std::string path = field.empty() ? key : field + "." + key;
    if (!value.IsDefined()) Fail(display_, Line(map), "missing key " + Quote(path));
    return value;
  }

  static std::string Join(const std::string& field, const std::string& key) {
    return field.empty() ? key : field + "." + key;
  }

  std::string Scalar(const YAML::Node& node, const std::string& field, const char* expected) const {
    if (!node.IsScalar()) FailAt(node, field, std::string("expected ") + expected);
    return node.Scalar();
  }

  double Double(const YAML::Node& map, const std::string& key, const std::string& field) const {
    const YAML::Node n = Get(map, key, field);
    return AsDouble(n, Join(field, key));
  }
  double AsDouble(const YAML::Node& n, const std::string& path) const {
    const std::string s = Scalar(n, path, "a number");
    double v;
    if (!ParseDouble(s, &v)) FailAt(n, path, "expected a finite number, got " + NotANumber(s));
    return v;
  }
  int Int(const YAML::Node& map, const std::string& key, const std::string& field) const {
    const YAML::Node n = Get(map, key, field);
    return AsInt(n, Join(field, key));
  }
  int AsInt(const YAML::Node& n, const std::string& path) const {
    const std::string s = Scalar(n, path, "an integer");
    int v;
    if (!ParseInt(s, &v)) FailAt(n, path, "expected an integer, got " + Quote(s));
    return v;
  }
  std::string String(const YAML::Node& map, const std::string& key,
                     const std::string& field) const {
    const YAML::Node n = Get(map, key, field);
    return Scalar(n, Join(field, key), "a string");
  }
  YAML::Node Sequence(const YAML::Node& map, const std::string& key, const std::string& field,
                      size_t required_size = 0) const {
    const YAML::Node n = Get(map, key, field);
    const std::string path = Join(field, key);
    if (!n.IsSequence()) FailAt(n, path, "expected a list");
    if (required_size > 0 && n.size() != required_size) {
      FailAt(n, path,
             "expected a list of " + std::to_string(required_size) + " elements, got " +
                 std::to_string(n.size()));
    }
    return n;
  }
  std::vector<int> IntList(const YAML::Node& map, const std::string& key,
                           const std::string& field) const {
    const YAML::Node n = Sequence(map, key, field);
    std::vector<int> out;
    for (size_t i = 0; i < n.size(); ++i) {
      out.push_back(AsInt(n[i], Join(field, key) + "[" + std::to_string(i) + "]"));
    }
    return out;
  }

  // Range-checked values: a value outside fails naming the file, line, field, the value and the
  // allowed range.
  struct Range {
    double lo, hi;
    bool lo_open = false, hi_open = false;  // (lo, ...] / [..., hi)
    bool Contains(double v) const {
      return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
    }
    std::string Text() const {
      return std::string(lo_open ? "(" : "[") + common::YamlDouble(lo) + ", " +
             common::YamlDouble(hi) + (hi_open ? ")" : "]");
    }
  };
  double AsDoubleIn(const YAML::Node& n, const std::string& path, const Range& r) const {
    const double v = AsDouble(n, path);
    if (!r.Contains(v))
      FailAt(n, path, "value " + common::YamlDouble(v) + " outside the allowed range " + r.Text());
    return v;
  }
  double DoubleIn(const YAML::Node& map, const std::string& key, const std::string& field,
                  const Range& r) const {
    return AsDoubleIn(Get(map, key, field), Join(field, key), r);
  }
  int AsIntIn(const YAML::Node& n, const std::string& path, int lo, int hi) const {
    const int v = AsInt(n, path);
    if (v < lo || v > hi) {
      FailAt(n, path,
             "value " + std::to_string(v) + " outside the allowed range [" + std::to_string(lo) +
                 ", " + std::to_string(hi) + "]");
    }
    return v;
  }
  int IntIn(const YAML::Node& map, const std::string& key, const std::string& field, int lo,
            int hi) const {
    return AsIntIn(Get(map, key, field), Join(field, key), lo, hi);
  }

  const std::string& display() const { return display_; }

 private:
  std::string display_;
};

// Allowed ranges of session.yaml and camera.yaml values (interchange-format.md). Wide enough for
// any real rig; their purpose is to stop absurd values (a 2e9 x 2e9 board, a zero square, a
// negative pose index) at the file instead of deep inside the solver.
namespace ranges {
using R = YamlReader::Range;
constexpr int kMinCorners = 2, kMaxCorners = 1000;  // inner corners per board direction
const R kSquareMm{0, 1000, /*lo_open=*/true};
constexpr int kMaxId = 1'000'000;  // beam ids, trigger indices, pose indices: [0, kMaxId]
// Drive and clock: a Keysight 33520B (30 MHz, 20 Vpp open circuit at most).
const R kFrequencyHz{0, 30e6, /*lo_open=*/true};
const R kAmplitudeVpp{0, 20};
const R kPhaseDeg{-360, 360};
const R kPatternPeriodS{0, 1e4, /*lo_open=*/true};
constexpr int kMaxImageSide = 100'000;  // pixels
const R kFocalPx{0, 1e7, /*lo_open=*/true};
const R kRadialDistortion{-1000, 1000};  // k1, k2, k3
const R kTangentialDistortion{-1, 1};    // p1, p2
}  // namespace ranges

std::string YamlDouble(double v) { return common::YamlDouble(v); }

// A plain scalar where that is unambiguous, else a double-quoted string.
std::string YamlString(const std::string& s) {
  bool plain = !s.empty();
  for (char c : s) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '/' ||
          c == '-')) {
      plain = false;
      break;
    }
  }
  if (plain && (s.front() == '-' || s.front() == '.')) plain = false;
  if (plain) {
    // Words that YAML would read as something other than a string.
    double d;
    static const std::set<std::string> kReserved = {
        "null", "Null", "NULL", "true", "True", "TRUE", "false", "False", "FALSE",
        "yes",  "Yes",  "YES",  "no",   "No",   "NO",   "on",    "On",    "ON",
        "off",  "Off",  "OFF",  "y",    "Y",    "n",    "N"};
    if (kReserved.count(s) || ParseDouble(s, &d)) plain = false;
  }
  if (plain) return s;
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof(buf), "\\x%02x", static_cast<unsigned char>(c));
          out += buf;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

std::string YamlIntList(const std::vector<int>& v) {
  std::string out = "[";
  for (size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + std::to_string(v[i]);
  return out + "]";
}

std::string FormatBoard(const dataset::BoardSpec& b) {
  return "{inner_corners: [" + std::to_string(b.cols) + ", " + std::to_string(b.rows) +
         "], square_mm: " + YamlDouble(b.square_mm) + "}";
}

std::string FormatAxis(const dataset::DriveAxis& a) {
  return "{frequency_hz: " + YamlDouble(a.frequency_hz) +
         ", amplitude_vpp: " + YamlDouble(a.amplitude_vpp) +
         ", phase_deg: " + YamlDouble(a.phase_deg) + "}";
}

dataset::BoardSpec ParseBoard(const YamlReader& y, const YAML::Node& boards, const char* key) {
  const std::string field = std::string("boards.") + key;
  const YAML::Node b = y.Get(boards, key, "boards");
  y.ExpectMap(b, field);
  const YAML::Node corners = y.Sequence(b, "inner_corners", field, 2);
  dataset::BoardSpec spec;
  spec.cols =
      y.AsIntIn(corners[0], field + ".inner_corners[0]", ranges::kMinCorners, ranges::kMaxCorners);
  spec.rows =
      y.AsIntIn(corners[1], field + ".inner_corners[1]", ranges::kMinCorners, ranges::kMaxCorners);
  spec.square_mm = y.DoubleIn(b, "square_mm", field, ranges::kSquareMm);
  return spec;
}

dataset::DriveAxis ParseAxis(const YamlReader& y, const YAML::Node& drive, const char* key) {
  const std::string field = std::string("drive.") + key;
  const YAML::Node a = y.Get(drive, key, "drive");
  dataset::DriveAxis axis;
  axis.frequency_hz = y.DoubleIn(a, "frequency_hz", field, ranges::kFrequencyHz);
  axis.amplitude_vpp = y.DoubleIn(a, "amplitude_vpp", field, ranges::kAmplitudeVpp);
  axis.phase_deg = y.DoubleIn(a, "phase_deg", field, ranges::kPhaseDeg);
  return axis;
}

// Lines of each frame node, kept to point reference errors at the right line.
struct FrameLines {
  std::vector<int> step1, step2, beams, triggers;
};

std::string CheckReferences(const dataset::Recording& r, const FrameLines* lines, int* line_out) {
  auto line_of = [&](const std::vector<int>* v, size_t i) {
    return lines && v && i < v->size() ? (*v)[i] : 0;
  };
  std::set<int> beam_ids, trigger_ids;
  for (size_t i = 0; i < r.beams.size(); ++i) {
    if (!beam_ids.insert(r.beams[i].id).second) {
      *line_out = line_of(lines ? &lines->beams : nullptr, i);
      return "field 'beams[" + std::to_string(i) + "].id': beam id " +
             std::to_string(r.beams[i].id) + " appears twice";
    }
  }
  for (size_t i = 0; i < r.triggers.size(); ++i) {
    if (!trigger_ids.insert(r.triggers[i].j).second) {
      *line_out = line_of(lines ? &lines->triggers : nullptr, i);
      return "field 'triggers[" + std::to_string(i) + "].j': trigger index " +
             std::to_string(r.triggers[i].j) + " appears twice";
    }
  }
  auto check_beams = [&](const std::vector<int>& beams, const std::string& field) {
    for (size_t k = 0; k < beams.size(); ++k) {
      if (!beam_ids.count(beams[k])) {
        return "field '" + field + ".beams[" + std::to_string(k) + "]': beam " +
               std::to_string(beams[k]) + " is not listed in 'beams'";
      }
    }
    return std::string();
  };
  for (size_t i = 0; i < r.step1.size(); ++i) {
    std::string e = check_beams(r.step1[i].beams, "step1.frames[" + std::to_string(i) + "]");
    if (!e.empty()) {
      *line_out = line_of(lines ? &lines->step1 : nullptr, i);
      return e;
    }
  }
  for (size_t i = 0; i < r.step2.size(); ++i) {
    const std::string field = "step2.frames[" + std::to_string(i) + "]";
    std::string e = check_beams(r.step2[i].beams, field);
    if (e.empty()) {
      for (size_t k = 0; k < r.step2[i].triggers.size(); ++k) {
        if (!trigger_ids.count(r.step2[i].triggers[k])) {
          e = "field '" + field + ".triggers[" + std::to_string(k) + "]': trigger index " +
              std::to_string(r.step2[i].triggers[k]) + " is not listed in 'triggers'";
          break;
        }
      }
    }
    if (!e.empty()) {
      *line_out = line_of(lines ? &lines->step2 : nullptr, i);
      return e;
    }
  }
  return "";
}

void ParseSession(const std::string& text, const std::string& display, dataset::Recording* rec) {
  const YamlReader y(display);
  const YAML::Node root = y.Load(text);
  if (!root.IsMap()) Fail(display, YamlReader::Line(root), "expected a mapping at the top level");
  const std::string format = y.String(root, "format", "");
  if (format != dataset::kInterchangeFormat) {
    y.FailAt(root["format"], "format",
             "unknown format version " + Quote(format) + ", expected " +
                 Quote(dataset::kInterchangeFormat));
  }
  rec->format = format;

  const YAML::Node boards = y.Get(root, "boards", "");
  rec->world_board = ParseBoard(y, boards, "world");
  rec->sliding_board = ParseBoard(y, boards, "sliding");

  FrameLines lines;
  const YAML::Node beams = y.Sequence(root, "beams", "");
  rec->beams.clear();
  for (size_t i = 0; i < beams.size(); ++i) {
    const std::string field = "beams[" + std::to_string(i) + "]";
    dataset::BeamSpec b;
    b.id = y.IntIn(beams[i], "id", field, 0, ranges::kMaxId);
    const std::string role = y.String(beams[i], "role", field);
    if (role == "estimate") {
      b.role = BeamRole::kEstimate;
    } else if (role == "validate") {
      b.role = BeamRole::kValidate;
    } else {
      y.FailAt(beams[i]["role"], field + ".role",
               "expected 'estimate' or 'validate', got " + Quote(role));
    }
    rec->beams.push_back(b);
    lines.beams.push_back(YamlReader::Line(beams[i]));
  }

  const YAML::Node drive = y.Get(root, "drive", "");
  rec->drive.fast = ParseAxis(y, drive, "fast");
  rec->drive.slow = ParseAxis(y, drive, "slow");
  rec->drive.pattern_period_s =
      y.DoubleIn(drive, "pattern_period_s", "drive", ranges::kPatternPeriodS);

  const YAML::Node clock = y.Get(root, "clock", "");
  rec->clock_frequency_hz = y.DoubleIn(clock, "frequency_hz", "clock", ranges::kFrequencyHz);

  const YAML::Node triggers = y.Sequence(root, "triggers", "");
  rec->triggers.clear();
  for (size_t i = 0; i < triggers.size(); ++i) {
    const std::string field = "triggers[" + std::to_string(i) + "]";
    dataset::Trigger t;
    t.j = y.IntIn(triggers[i], "j", field, 0, ranges::kMaxId);
    // A pulse time within the pattern period.
    t.t_s = y.DoubleIn(triggers[i], "t_s", field, {0, rec->drive.pattern_period_s});
    rec->triggers.push_back(t);
    lines.triggers.push_back(YamlReader::Line(triggers[i]));
  }

  const YAML::Node step1 = y.Sequence(y.Get(root, "step1", ""), "frames", "step1");
  rec->step1.clear();
  for (size_t i = 0; i < step1.size(); ++i) {
    const std::string field = "step1.frames[" + std::to_string(i) + "]";
    dataset::Step1Frame f;
    f.file = y.String(step1[i], "file", field);
    f.pose = y.IntIn(step1[i], "pose", field, 0, ranges::kMaxId);
    f.beams = y.IntList(step1[i], "beams", field);
    rec->step1.push_back(f);
    lines.step1.push_back(YamlReader::Line(step1[i]));
  }

  const YAML::Node step2 = y.Sequence(y.Get(root, "step2", ""), "frames", "step2");
  rec->step2.clear();
  for (size_t i = 0; i < step2.size(); ++i) {
    const std::string field = "step2.frames[" + std::to_string(i) + "]";
    dataset::Step2Frame f;
    f.file = y.String(step2[i], "file", field);
    const std::string kind = y.String(step2[i], "kind", field);
    if (kind == "neutral") {
      f.kind = Step2Kind::kNeutral;
    } else if (kind == "fast_only") {
      f.kind = Step2Kind::kFastOnly;
    } else if (kind == "scan") {
      f.kind = Step2Kind::kScan;
    } else {
      y.FailAt(step2[i]["kind"], field + ".kind",
               "expected 'neutral', 'fast_only' or 'scan', got " + Quote(kind));
    }
    // Neutral frames may omit their (empty) trigger list; moving frames must list theirs.
    if (f.kind != Step2Kind::kNeutral || step2[i]["triggers"].IsDefined()) {
      f.triggers = y.IntList(step2[i], "triggers", field);
    }
    f.beams = y.IntList(step2[i], "beams", field);
    rec->step2.push_back(f);
    lines.step2.push_back(YamlReader::Line(step2[i]));
  }

  int line = 0;
  const std::string problem = CheckReferences(*rec, &lines, &line);
  if (!problem.empty()) Fail(display, line, problem);
}

geometry::CameraModel ParseCamera(const std::string& text, const std::string& display) {
  const YamlReader y(display);
  const YAML::Node root = y.Load(text);
  if (!root.IsMap()) Fail(display, YamlReader::Line(root), "expected a mapping at the top level");
  geometry::CameraModel cam;
  const YAML::Node size = y.Sequence(root, "image_size", "", 2);
  cam.width = y.AsIntIn(size[0], "image_size[0]", 1, ranges::kMaxImageSide);
  cam.height = y.AsIntIn(size[1], "image_size[1]", 1, ranges::kMaxImageSide);
  const YAML::Node k = y.Sequence(root, "K", "", 3);
  double m[3][3];
  for (int r = 0; r < 3; ++r) {
    const std::string row_field = "K[" + std::to_string(r) + "]";
    if (!k[r].IsSequence() || k[r].size() != 3) {
      y.FailAt(k[r], row_field, "expected a list of 3 numbers");
    }
    for (int c = 0; c < 3; ++c) {
      m[r][c] = y.AsDouble(k[r][c], row_field + "[" + std::to_string(c) + "]");
    }
  }
  if (m[0][1] != 0 || m[1][0] != 0 || m[2][0] != 0 || m[2][1] != 0 || m[2][2] != 1) {
    y.FailAt(k, "K", "expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew)");
  }
  // Focal lengths positive; the principal point within one image size of the image.
  cam.fx = y.AsDoubleIn(k[0][0], "K[0][0]", ranges::kFocalPx);
  cam.cx = y.AsDoubleIn(k[0][2], "K[0][2]", {-1.0 * cam.width, 2.0 * cam.width});
  cam.fy = y.AsDoubleIn(k[1][1], "K[1][1]", ranges::kFocalPx);
  cam.cy = y.AsDoubleIn(k[1][2], "K[1][2]", {-1.0 * cam.height, 2.0 * cam.height});
  const YAML::Node dist = y.Sequence(root, "distortion", "", 5);
  for (int i = 0; i < 5; ++i) {
    const bool tangential = i == 2 || i == 3;  // k1 k2 p1 p2 k3
    cam.distortion[i] =
        y.AsDoubleIn(dist[i], "distortion[" + std::to_string(i) + "]",
                     tangential ? ranges::kTangentialDistortion : ranges::kRadialDistortion);
  }
  const std::string problem = cam.Validate();
  if (!problem.empty()) Fail(display, YamlReader::Line(root), problem);
  return cam;
}

// Fails if `file` (relative to the folder) is not a usable relative path or does not exist.
void CheckImage(const fs::path& dir, const std::string& file, const std::string& display,
                const std::string& field, int line) {
  const fs::path rel(file);
  if (rel.is_absolute() || file.empty()) {
    Fail(display, line,
         "field " + Quote(field) + ": expected a path relative to the folder, got " + Quote(file));
  }
  for (const auto& part : rel) {
    if (part == "..") {
      Fail(display, line, "field " + Quote(field) + ": path " + Quote(file) + " leaves the folder");
    }
  }
  std::error_code ec;
  if (!fs::is_regular_file(dir / rel, ec)) {
    Fail(display, line,
         "field " + Quote(field) + ": referenced image " + Quote(file) + " not found");
  }
}

}  // namespace

// ------------------------------------------------------------------------------ public functions

std::string FormatDouble(double value) { return common::ShortestDouble(value); }

void WriteFileAtomically(const std::filesystem::path& file, const std::string& contents) {
  try {
    common::WriteFileAtomically(file, contents);
  } catch (const std::runtime_error& e) {
    throw InterchangeError(e.what());
  }
}

void WriteImageAtomically(const std::filesystem::path& file, const cv::Mat& image) {
  const int depth = image.depth();
  const int channels = image.channels();
  if (image.empty() || (depth != CV_8U && depth != CV_16U) || (channels != 1 && channels != 3)) {
    Fail(file.string(), 0,
         "image must be a non-empty 8- or 16-bit mono or BGR image, got " +
             std::to_string(image.cols) + "x" + std::to_string(image.rows) + " depth " +
             std::to_string(depth) + " with " + std::to_string(channels) + " channels");
  }
  std::vector<uchar> png;
  try {
    if (!cv::imencode(".png", image, png)) Fail(file.string(), 0, "PNG encoding failed");
  } catch (const cv::Exception& e) {
    Fail(file.string(), 0, std::string("PNG encoding failed: ") + e.what());
  }
  WriteFileAtomically(file, std::string(png.begin(), png.end()));
}

std::string ImageProblem(const cv::Mat& image, const geometry::CameraModel& camera) {
  if ((image.depth() != CV_8U && image.depth() != CV_16U) ||
      (image.channels() != 1 && image.channels() != 3)) {
    return "expected 8- or 16-bit mono or BGR, got depth " + std::to_string(image.depth()) +
           " with " + std::to_string(image.channels()) + " channels";
  }
  if (image.cols != camera.width || image.rows != camera.height) {
    return "image is " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
           " but camera.yaml image_size is [" + std::to_string(camera.width) + ", " +
           std::to_string(camera.height) + "]";
  }
  return "";
}

void CheckImageFiles(const std::filesystem::path& dir, const dataset::Recording& recording) {
  auto check = [&](const std::string& file, const std::string& field) {
    const std::string where = file + " (" + field + ")";
    std::error_code ec;
    if (!fs::is_regular_file(dir / file, ec)) Fail(where, 0, "image not found");
    const std::string bytes = ReadWholeFile(dir / file, where);
    static const std::string kPngSignature = "\x89PNG\r\n\x1a\n";
    if (bytes.compare(0, kPngSignature.size(), kPngSignature) != 0) {
      Fail(where, 0, "not a PNG file (no PNG signature)");
    }
    cv::Mat image;
    try {
      image = cv::imdecode(
          cv::Mat(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data())),
          cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception& e) {
      Fail(where, 0, std::string("cannot decode: ") + e.what());
    }
    if (image.empty()) Fail(where, 0, "cannot decode the PNG");
    if (std::string problem = ImageProblem(image, recording.camera); !problem.empty())
      Fail(where, 0, problem);
  };
  for (size_t i = 0; i < recording.step1.size(); ++i) {
    check(recording.step1[i].file, "step1.frames[" + std::to_string(i) + "].file");
  }
  for (size_t i = 0; i < recording.step2.size(); ++i) {
    check(recording.step2[i].file, "step2.frames[" + std::to_string(i) + "].file");
  }
}

std::string FormatCameraYaml(const geometry::CameraModel& c) {
  std::string out;
  out += "image_size: [" + std::to_string(c.width) + ", " + std::to_string(c.height) + "]\n";
  out += "K: [[" + YamlDouble(c.fx) + ", 0, " + YamlDouble(c.cx) + "], [0, " + YamlDouble(c.fy) +
         ", " + YamlDouble(c.cy) + "], [0, 0, 1]]\n";
  out += "distortion: [";
  for (size_t i = 0; i < c.distortion.size(); ++i) {
    out += (i ? ", " : "") + YamlDouble(c.distortion[i]);
  }
  out += "]\n";
  return out;
}

std::string FormatSessionYaml(const dataset::Recording& r) {
  std::string out;
  out += "format: " + YamlString(r.format) + "\n";
  out += "boards:\n";
  out += "  world: " + FormatBoard(r.world_board) + "\n";
  out += "  sliding: " + FormatBoard(r.sliding_board) + "\n";
  out += "beams:";
  out += r.beams.empty() ? " []\n" : "\n";
  for (const auto& b : r.beams) {
    out += "  - {id: " + std::to_string(b.id) + ", role: " + dataset::ToString(b.role) + "}\n";
  }
  out += "drive:\n";
  out += "  fast: " + FormatAxis(r.drive.fast) + "\n";
  out += "  slow: " + FormatAxis(r.drive.slow) + "\n";
  out += "  pattern_period_s: " + YamlDouble(r.drive.pattern_period_s) + "\n";
  out += "clock:\n";
  out += "  frequency_hz: " + YamlDouble(r.clock_frequency_hz) + "\n";
  out += "triggers:";
  out += r.triggers.empty() ? " []\n" : "\n";
  for (const auto& t : r.triggers) {
    out += "  - {j: " + std::to_string(t.j) + ", t_s: " + YamlDouble(t.t_s) + "}\n";
  }
  out += "step1:\n  frames:";
  out += r.step1.empty() ? " []\n" : "\n";
  for (const auto& f : r.step1) {
    out += "    - {file: " + YamlString(f.file) + ", pose: " + std::to_string(f.pose) +
           ", beams: " + YamlIntList(f.beams) + "}\n";
  }
  out += "step2:\n  frames:";
  out += r.step2.empty() ? " []\n" : "\n";
  for (const auto& f : r.step2) {
    out += "    - {file: " + YamlString(f.file) + ", kind: " + dataset::ToString(f.kind);
    if (f.kind != Step2Kind::kNeutral || !f.triggers.empty()) {
      out += ", triggers: " + YamlIntList(f.triggers);
    }
    out += ", beams: " + YamlIntList(f.beams) + "}\n";
  }
  return out;
}

void ParseSessionYaml(const std::string& text, const std::string& display_name,
                      dataset::Recording* recording) {
  ParseSession(text, display_name, recording);
}

geometry::CameraModel ParseCameraYaml(const std::string& text, const std::string& display_name) {
  return ParseCamera(text, display_name);
}

std::string CheckRecording(const dataset::Recording& r) {
  int line = 0;
  std::string problem = CheckReferences(r, nullptr, &line);
  if (!problem.empty()) return problem;
  auto check_clock = [](const std::optional<dataset::HallRecording>& h, const char* name) {
    if (!h) return std::string();
    for (size_t i = 1; i < h->clock_edges_us.size(); ++i) {
      if (h->clock_edges_us[i] <= h->clock_edges_us[i - 1]) {
        return std::string("field '") + name + ".clock_edges_us[" + std::to_string(i) +
               "]': clock edges must be strictly ascending";
      }
    }
    return std::string();
  };
  problem = check_clock(r.hall_actual, "hall_actual");
  if (problem.empty()) problem = check_clock(r.hall_background, "hall_background");
  return problem;
}

dataset::Recording ReadRecording(const std::filesystem::path& dir, ReadParts parts) {
  dataset::Recording rec;
  ParseSession(ReadWholeFile(dir / "session.yaml", "session.yaml"), "session.yaml", &rec);
  rec.camera = ParseCamera(ReadWholeFile(dir / "camera.yaml", "camera.yaml"), "camera.yaml");

  // Image references: re-parse only for the lines of the offending frame.
  for (size_t i = 0; i < rec.step1.size() + rec.step2.size(); ++i) {
    const bool first = i < rec.step1.size();
    const std::string& file = first ? rec.step1[i].file : rec.step2[i - rec.step1.size()].file;
    std::error_code ec;
    const fs::path rel(file);
    bool ok = !file.empty() && !rel.is_absolute() && fs::is_regular_file(dir / rel, ec);
    for (const auto& part : rel) ok = ok && part != "..";
    if (ok) continue;
    const size_t index = first ? i : i - rec.step1.size();
    const std::string field =
        std::string(first ? "step1" : "step2") + ".frames[" + std::to_string(index) + "].file";
    const YAML::Node root = YAML::Load(ReadWholeFile(dir / "session.yaml", "session.yaml"));
    const YAML::Node frame = root[first ? "step1" : "step2"]["frames"][index];
    CheckImage(dir, file, "session.yaml", field, YamlReader::Line(frame));
  }

  std::error_code ec;
  if (parts.hall &&
      (fs::exists(dir / "hall/actual.csv", ec) || fs::exists(dir / "hall/actual_clock.csv", ec))) {
    rec.hall_actual = ReadHall(dir / "hall/actual.csv", "hall/actual.csv",
                               dir / "hall/actual_clock.csv", "hall/actual_clock.csv");
  }
  if (parts.hall && (fs::exists(dir / "hall/background.csv", ec) ||
                     fs::exists(dir / "hall/background_clock.csv", ec))) {
    rec.hall_background = ReadHall(dir / "hall/background.csv", "hall/background.csv",
                                   dir / "hall/background_clock.csv", "hall/background_clock.csv");
  }
  if (parts.marg && fs::exists(dir / "marg/plane_rotation.csv", ec)) {
    rec.marg_plane_rotation = ReadMarg(dir / "marg/plane_rotation.csv", "marg/plane_rotation.csv");
  }
  if (parts.marg && fs::exists(dir / "marg/free_rotation.csv", ec)) {
    rec.marg_free_rotation = ReadMarg(dir / "marg/free_rotation.csv", "marg/free_rotation.csv");
  }
  if (parts.marg && fs::exists(dir / "marg/validation.csv", ec)) {
    rec.marg_validation = ReadMarg(dir / "marg/validation.csv", "marg/validation.csv");
  }
  return rec;
}

void WriteRecording(const std::filesystem::path& dir, const dataset::Recording& recording) {
  const std::string problem = CheckRecording(recording);
  if (!problem.empty()) {
    Fail(dir.string(), 0, "refusing to write an inconsistent recording: " + problem);
  }
  WriteFileAtomically(dir / "camera.yaml", FormatCameraYaml(recording.camera));
  if (recording.hall_actual) {
    WriteHallCsv(dir / "hall/actual.csv", dir / "hall/actual_clock.csv", *recording.hall_actual);
  }
  if (recording.hall_background) {
    WriteHallCsv(dir / "hall/background.csv", dir / "hall/background_clock.csv",
                 *recording.hall_background);
  }
  if (recording.marg_plane_rotation) {
    WriteMargCsv(dir / "marg/plane_rotation.csv", *recording.marg_plane_rotation);
  }
  if (recording.marg_free_rotation) {
    WriteMargCsv(dir / "marg/free_rotation.csv", *recording.marg_free_rotation);
  }
  if (recording.marg_validation) {
    WriteMargCsv(dir / "marg/validation.csv", *recording.marg_validation);
  }
  // session.yaml last: a folder with a session.yaml is complete.
  WriteFileAtomically(dir / "session.yaml", FormatSessionYaml(recording));
}

geometry::CameraModel ReadCameraYaml(const std::filesystem::path& file) {
  return ParseCamera(ReadWholeFile(file, file.string()), file.string());
}

void WriteCameraYaml(const std::filesystem::path& file, const geometry::CameraModel& camera) {
  WriteFileAtomically(file, FormatCameraYaml(camera));
}

dataset::HallRecording ReadHallCsv(const std::filesystem::path& readings_csv,
                                   const std::filesystem::path& clock_csv) {
  return ReadHall(readings_csv, readings_csv.string(), clock_csv, clock_csv.string());
}

void WriteHallCsv(const std::filesystem::path& readings_csv, const std::filesystem::path& clock_csv,
                  const dataset::HallRecording& hall) {
  for (size_t i = 1; i < hall.clock_edges_us.size(); ++i) {
    if (hall.clock_edges_us[i] <= hall.clock_edges_us[i - 1]) {
      Fail(clock_csv.string(), 0,
           "refusing to write clock edges that are not strictly ascending (edge " +
               std::to_string(i) + ")");
    }
  }
  WriteFileAtomically(clock_csv, FormatClockEdges(hall.clock_edges_us));
  WriteFileAtomically(readings_csv, FormatHallReadings(hall.readings));
}

std::vector<dataset::HallReading> ReadHallReadingsCsv(const std::filesystem::path& file) {
  return ReadHallReadings(file, file.string());
}

void WriteHallReadingsCsv(const std::filesystem::path& file,
                          const std::vector<dataset::HallReading>& readings) {
  WriteFileAtomically(file, FormatHallReadings(readings));
}

dataset::MargRecording ReadMargCsv(const std::filesystem::path& file) {
  return ReadMarg(file, file.string());
}

void WriteMargCsv(const std::filesystem::path& file, const dataset::MargRecording& recording) {
  WriteFileAtomically(file, FormatMarg(recording));
}

std::vector<dataset::HallReading> ParseHallReadingsCsv(const std::string& text,
                                                       const std::string& display_name) {
  CsvReader csv(CsvReader::Text{text}, display_name, {kHallHeader});
  return HallReadingRows(csv);
}

std::vector<double> ParseClockEdgesCsv(const std::string& text, const std::string& display_name) {
  CsvReader csv(CsvReader::Text{text}, display_name, {kClockHeader});
  return ClockEdgeRows(csv);
}

dataset::MargRecording ParseMargCsv(const std::string& text, const std::string& display_name) {
  CsvReader csv(CsvReader::Text{text}, display_name, {kMargFullHeader, kMargMagHeader});
  return MargRows(csv);
}

std::string FormatHallReadingsCsv(const std::vector<dataset::HallReading>& readings) {
  return FormatHallReadings(readings);
}

std::string FormatClockEdgesCsv(const std::vector<double>& edges) {
  return FormatClockEdges(edges);
}

std::string FormatMargCsv(const dataset::MargRecording& recording) { return FormatMarg(recording); }

}  // namespace msmcal::interchange
