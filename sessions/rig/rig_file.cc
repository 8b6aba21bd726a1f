#include "sessions/rig/rig_file.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "common/yaml_fields.h"
#include "processing/signal/rig_signals.h"

namespace msmcal::rig {
namespace {

using common::FieldNumber;

// Reads one document over the shared field reader (common/yaml_fields.h), failing as
// "origin:line: field<what>" (`what` is ": problem" or " = value: rule").
class Reader {
 public:
  explicit Reader(std::string origin) : fields_(std::move(origin)) {}

  [[noreturn]] void Fail(const YAML::Node& node, const std::string& field,
                         const std::string& what) const {
    fields_.FailText(node, field + what);
  }

  std::string KeyAt(const YAML::Node& key, const std::string& field) const {
    return fields_.KeyAt(key, field);
  }

  // The mapping `parent[key]`; unknown keys refused. Missing: a null node when `optional`.
  YAML::Node Map(const YAML::Node& parent, const std::string& key, const std::string& field,
                 const std::set<std::string>& allowed, bool optional = false) const {
    return fields_.Map(parent, key, field, allowed, optional);
  }

  // A finite number in [lo, hi] (lo excluded when `lo_open`).
  double Number(const YAML::Node& parent, const std::string& key, const std::string& field,
                std::optional<double> def, double lo, double hi, bool lo_open = false) const {
    return fields_.Number(parent, key, field, def, Rule(lo, hi, lo_open));
  }

  double NumberAt(const YAML::Node& n, const std::string& field, double lo, double hi,
                  bool lo_open = false) const {
    return fields_.NumberAt(n, field, Rule(lo, hi, lo_open));
  }

  int Int(const YAML::Node& parent, const std::string& key, const std::string& field,
          std::optional<int> def, int lo, int hi) const {
    return fields_.Int(parent, key, field, def, lo, hi);
  }

  int IntAt(const YAML::Node& n, const std::string& field, int lo, int hi) const {
    return fields_.IntAt(n, field, lo, hi);
  }

  bool Bool(const YAML::Node& parent, const std::string& key, const std::string& field,
            bool def) const {
    return fields_.Bool(parent, key, field, def);
  }

  std::string String(const YAML::Node& parent, const std::string& key,
                     const std::string& field) const {
    return fields_.String(parent, key, field, std::nullopt, /*non_empty=*/true);
  }

  YAML::Node Load(const std::string& text) const { return fields_.Load(text); }

 private:
  static common::NumberRule Rule(double lo, double hi, bool lo_open) {
    return lo_open ? common::NumberRule::Above(lo, hi) : common::NumberRule::In(lo, hi);
  }

  common::YamlFields fields_;
};

// The node a validation message's leading field path names ("generators.unit1.ch1 (...): ..."),
// as deep as the document has it: the message then carries that node's line.
YAML::Node NodeOfField(const YAML::Node& root, const std::string& message) {
  const size_t end = message.find_first_of(" :(=");
  std::stringstream path(message.substr(0, end));
  std::string part;
  YAML::Node at = root;
  while (std::getline(path, part, '.')) {
    if (part.size() == 3 && part[0] == 'c' && part[1] == 'h') {  // "ch1": channels.1
      const YAML::Node chs = at["channels"];
      if (!chs || !chs[part.substr(2)]) break;
      at = chs[part.substr(2)];
      continue;
    }
    if (!at.IsMap() || !at[part]) break;
    at = at[part];
  }
  return at;
}

void ReadCamera(const Reader& r, const YAML::Node& root, double pattern_period_s, RigCamera* c) {
  const std::string f = "camera";
  const YAML::Node n = r.Map(root, "camera", f,
                             {"kind", "address", "device", "frame_rate_hz", "exposure_us", "width",
                              "height", "fx", "fy", "cx", "cy", "distortion"});
  const std::string kind = r.String(n, "kind", f + ".kind");
  if (kind == "gige") {
    c->kind = CameraKind::kGige;
    c->address = r.String(n, "address", f + ".address");
    if (n["device"]) r.Fail(n["device"], f + ".device", ": only for kind v4l2 (this is gige)");
  } else if (kind == "v4l2") {
    c->kind = CameraKind::kV4l2;
    c->device = r.String(n, "device", f + ".device");
    if (c->device.front() != '/')
      r.Fail(n["device"], f + ".device", " = '" + c->device + "': must be an absolute path");
    if (n["address"]) r.Fail(n["address"], f + ".address", ": only for kind gige (this is v4l2)");
  } else {
    r.Fail(n["kind"], f + ".kind", " = '" + kind + "': must be gige or v4l2");
  }
  c->frame_rate_hz =
      r.Number(n, "frame_rate_hz", f + ".frame_rate_hz", 10.0, 0, kMaxFrameRateHz, true);
  c->exposure_us = r.Number(n, "exposure_us", f + ".exposure_us", 20000.0, 0, 1e7, true);
  const double period_us = 1e6 / c->frame_rate_hz;
  if (c->exposure_us > period_us) {
    r.Fail(n["exposure_us"], f + ".exposure_us",
           " = " + FieldNumber(c->exposure_us) +
               ": must be <= the frame period 1e6 / frame_rate_hz = " + FieldNumber(period_us) +
               " us");
  }
  // A frame collects every trigger of its pattern only when it is exposed for a whole pattern
  // period (each trigger fires once per period).
  if (pattern_period_s > 0 && c->exposure_us < pattern_period_s * 1e6 * (1 - 1e-9)) {
    r.Fail(n["exposure_us"], f + ".exposure_us",
           " = " + FieldNumber(c->exposure_us) +
               ": must be >= the drives' pattern period (generators.signals.drive: 1 / gcd of "
               "the fast and slow frequencies) = " +
               FieldNumber(pattern_period_s * 1e6) +
               " us, so that a frame collects every trigger of its pattern (lower "
               "camera.frame_rate_hz to at most 1e6 / exposure_us)");
  }
  geometry::CameraModel& m = c->model;
  m.width = r.Int(n, "width", f + ".width", std::nullopt, 16, 30000);
  m.height = r.Int(n, "height", f + ".height", std::nullopt, 16, 30000);
  m.fx = r.Number(n, "fx", f + ".fx", std::nullopt, 0, 1e6, true);
  m.fy = r.Number(n, "fy", f + ".fy", std::nullopt, 0, 1e6, true);
  m.cx = r.Number(n, "cx", f + ".cx", std::nullopt, -0.5, m.width - 0.5);
  m.cy = r.Number(n, "cy", f + ".cy", std::nullopt, -0.5, m.height - 0.5);
  m.distortion = {0, 0, 0, 0, 0};
  if (const YAML::Node d = n["distortion"]) {
    if (!d.IsSequence() || d.size() != 5)
      r.Fail(d, f + ".distortion", ": must be a list of 5 numbers [k1, k2, p1, p2, k3]");
    for (size_t i = 0; i < 5; ++i) {
      m.distortion[i] = r.NumberAt(d[i], f + ".distortion[" + std::to_string(i) + "]", -100, 100);
    }
  }
}

dataset::BoardSpec ReadBoard(const Reader& r, const YAML::Node& boards, const std::string& key) {
  const std::string f = "boards." + key;
  const YAML::Node n = r.Map(boards, key, f, {"cols", "rows", "square_mm"});
  dataset::BoardSpec b;
  b.cols = r.Int(n, "cols", f + ".cols", std::nullopt, 3, 199);
  b.rows = r.Int(n, "rows", f + ".rows", std::nullopt, 2, 198);
  b.square_mm = r.Number(n, "square_mm", f + ".square_mm", std::nullopt, 0, 1000, true);
  // Interchange format: (cols + 1) even and (rows + 1) odd pick exactly one origin corner.
  if (b.cols % 2 == 0)
    r.Fail(n["cols"], f + ".cols",
           " = " + std::to_string(b.cols) + ": must be odd (unique origin corner)");
  if (b.rows % 2 != 0)
    r.Fail(n["rows"], f + ".rows",
           " = " + std::to_string(b.rows) + ": must be even (unique origin corner)");
  return b;
}

}  // namespace

const char* ToString(CameraKind kind) { return kind == CameraKind::kGige ? "gige" : "v4l2"; }

std::string RigCamera::OpenString() const {
  return kind == CameraKind::kGige ? address : "v4l2:" + device;
}

double SlidingPlate::DistanceMm(int pose) const {
  return nearest_mm + (poses > 1 ? pose * (farthest_mm - nearest_mm) / (poses - 1) : 0.0);
}

double SlidingPlate::TiltDeg(int pose) const { return (pose % 2 == 0 ? 1 : -1) * tilt_deg; }

std::string RigCamera::CheckFrameRate(double hz) const {
  if (!std::isfinite(hz) || !(hz > 0) || hz > kMaxFrameRateHz)
    return "must be in (0, " + FieldNumber(kMaxFrameRateHz) + "] Hz";
  if (exposure_us > 1e6 / hz)
    return "its frame period 1e6 / " + FieldNumber(hz) + " = " + FieldNumber(1e6 / hz) +
           " us is shorter than camera.exposure_us = " + FieldNumber(exposure_us) + " us";
  return "";
}

RigFile ParseRigFile(const std::string& yaml_text, const std::string& origin) {
  RigFile rf;
  rf.origin = origin;
  rf.text = yaml_text;
  const Reader r(origin);
  const YAML::Node root = r.Load(yaml_text);
  if (!root.IsMap()) r.Fail(root, "(root)", ": must be a mapping of sections");
  const std::set<std::string> sections = {"generators", "camera",        "hall_mcu", "boards",
                                          "beams",      "sliding_plate", "step1",    "step2"};
  for (const auto& kv : root) {
    const std::string k = r.KeyAt(kv.first, "(root)");
    if (!sections.count(k)) {
      r.Fail(kv.first, k,
             ": unknown section (a rig file has generators, camera, hall_mcu, boards, beams, "
             "sliding_plate, step1, step2)");
    }
  }
  // generators: and hall_mcu: through their own loaders (they name file, line and field).
  rf.generators = gen::ParseRigGeneratorConfig(yaml_text, origin);
  if (std::string e = rf.generators.Validate(); !e.empty()) {
    // A trigger design refusal is about the `trigger:` settings.
    const bool trigger = e.rfind("generators.signals: trigger design", 0) == 0;
    const YAML::Node at = trigger ? root["generators"]["signals"]["trigger"] : NodeOfField(root, e);
    r.Fail(at, e, "");
  }
  rf.hall_mcu = hall_mcu::ParseHallMcuConfig(yaml_text, origin);
  ReadCamera(r, root,
             signal::PatternPeriod(rf.generators.signals.fast.frequency_hz,
                                   rf.generators.signals.slow.frequency_hz),
             &rf.camera);

  const YAML::Node boards = r.Map(root, "boards", "boards", {"world", "sliding"});
  rf.world_board = ReadBoard(r, boards, "world");
  rf.sliding_board = ReadBoard(r, boards, "sliding");

  const YAML::Node beams = r.Map(root, "beams", "beams", {"count", "validate"});
  rf.beams.count = r.Int(beams, "count", "beams.count", std::nullopt, 2, 16);
  if (const YAML::Node v = beams["validate"]) {
    if (!v.IsSequence()) r.Fail(v, "beams.validate", ": must be a list of beam ids");
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string fi = "beams.validate[" + std::to_string(i) + "]";
      const int id = r.IntAt(v[i], fi, 1, rf.beams.count);
      if (std::count(rf.beams.validate_ids.begin(), rf.beams.validate_ids.end(), id))
        r.Fail(v[i], fi, " = " + std::to_string(id) + ": listed twice");
      rf.beams.validate_ids.push_back(id);
    }
    const int estimate = rf.beams.count - static_cast<int>(rf.beams.validate_ids.size());
    if (estimate < 2) {
      r.Fail(v, "beams.validate",
             ": leaves " + std::to_string(estimate) +
                 " beam(s) to estimate from; the solver needs at least 2");
    }
  }

  const std::string pf = "sliding_plate";
  const YAML::Node plate =
      r.Map(root, "sliding_plate", pf,
            {"poses", "nearest_mm", "farthest_mm", "tilt_deg", "dot_margin_squares"});
  SlidingPlate& p = rf.sliding_plate;
  p.poses = r.Int(plate, "poses", pf + ".poses", std::nullopt, 2, 50);
  p.nearest_mm = r.Number(plate, "nearest_mm", pf + ".nearest_mm", std::nullopt, 0, 2000, true);
  p.farthest_mm =
      r.Number(plate, "farthest_mm", pf + ".farthest_mm", std::nullopt, p.nearest_mm, 2000, true);
  p.tilt_deg = r.Number(plate, "tilt_deg", pf + ".tilt_deg", 0.0, 0, 60);
  p.dot_margin_squares = r.Number(plate, "dot_margin_squares", pf + ".dot_margin_squares",
                                  p.dot_margin_squares, 0, 100);

  const YAML::Node s1 =
      r.Map(root, "step1", "step1", {"exposures", "identification_frames", "background_frames"},
            /*optional=*/true);
  Step1Design& d1 = rf.step1;
  d1.exposures = r.Int(s1, "exposures", "step1.exposures", d1.exposures, 1, 20);
  d1.identification_frames =
      r.Bool(s1, "identification_frames", "step1.identification_frames", d1.identification_frames);
  d1.background_frames =
      r.Bool(s1, "background_frames", "step1.background_frames", d1.background_frames);

  const YAML::Node s2 = r.Map(root, "step2", "step2",
                              {"neutral_frames", "fast_only_frames", "fast_only_triggers_per_frame",
                               "scan_triggers_per_frame", "frame_min_separation", "exposures",
                               "hall_background_s", "hall_actual_min_s", "dot_margin_squares"},
                              /*optional=*/true);
  Step2Design& d2 = rf.step2;
  d2.neutral_frames = r.Int(s2, "neutral_frames", "step2.neutral_frames", d2.neutral_frames, 0, 50);
  d2.fast_only_frames =
      r.Int(s2, "fast_only_frames", "step2.fast_only_frames", d2.fast_only_frames, 0, 50);
  d2.fast_only_triggers_per_frame =
      r.Int(s2, "fast_only_triggers_per_frame", "step2.fast_only_triggers_per_frame",
            d2.fast_only_triggers_per_frame, 1, 64);
  d2.scan_triggers_per_frame = r.Int(s2, "scan_triggers_per_frame", "step2.scan_triggers_per_frame",
                                     d2.scan_triggers_per_frame, 1, 64);
  const double min_sep = rf.generators.signals.trigger.min_separation;
  d2.frame_min_separation = r.Number(s2, "frame_min_separation", "step2.frame_min_separation",
                                     d2.frame_min_separation, min_sep, 2.0 * std::sqrt(2.0));
  d2.exposures = r.Int(s2, "exposures", "step2.exposures", d2.exposures, 1, 20);
  d2.hall_background_s = r.Number(s2, "hall_background_s", "step2.hall_background_s",
                                  d2.hall_background_s, 0, 3600, true);
  d2.hall_actual_min_s =
      r.Number(s2, "hall_actual_min_s", "step2.hall_actual_min_s", d2.hall_actual_min_s, 0, 3600);
  d2.dot_margin_squares =
      r.Number(s2, "dot_margin_squares", "step2.dot_margin_squares", d2.dot_margin_squares, 0, 100);
  return rf;
}

RigFile LoadRigFile(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file.string() + ": cannot read the rig file");
  std::stringstream ss;
  ss << in.rdbuf();
  return ParseRigFile(ss.str(), file.string());
}

}  // namespace msmcal::rig
