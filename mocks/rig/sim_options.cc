#include "mocks/rig/sim_options.h"

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <functional>
#include <numeric>
#include <set>
#include <sstream>
#include <stdexcept>

#include "common/file_text.h"
#include "common/text_io.h"
#include "common/yaml_fields.h"

namespace msmcal::sim {
namespace {

// Visits every field of SimOptions once, so that parsing and emitting share one field list.
template <typename V>
void VisitAxis(V& v, AxisOptions& a) {
  v.Field("frequency_hz", a.frequency_hz);
  v.Field("amplitude_vpp", a.amplitude_vpp);
  v.Field("phase_deg", a.phase_deg);
  v.Field("resonance_hz", a.resonance_hz);
  v.Field("q", a.q);
  v.Field("dc_gain_deg_per_v", a.dc_gain_deg_per_v);
  v.Field("harmonic2_ratio", a.harmonic2_ratio);
  v.Field("harmonic2_phase_deg", a.harmonic2_phase_deg);
}

template <typename V>
void VisitBoard(V& v, BoardOptions& b) {
  v.Field("cols", b.cols);
  v.Field("rows", b.rows);
  v.Field("square_mm", b.square_mm);
}

template <typename V>
void VisitAll(V& v, SimOptions& o) {
  v.Field("seed", o.seed);
  v.Group("mirror", [&] {
    v.Group("fast", [&] { VisitAxis(v, o.mirror.fast); });
    v.Group("slow", [&] { VisitAxis(v, o.mirror.slow); });
    v.Field("trans_offset_mm", o.mirror.trans_offset_mm);
    v.Field("trans_k_beta_mm_per_deg", o.mirror.trans_k_beta_mm_per_deg);
    v.Field("trans_k_alpha2_mm_per_deg2", o.mirror.trans_k_alpha2_mm_per_deg2);
    v.Field("trans_k_beta2_mm_per_deg2", o.mirror.trans_k_beta2_mm_per_deg2);
  });
  v.Group("geometry", [&] {
    auto& g = o.geometry;
    v.Field("mirror_distance_mm", g.mirror_distance_mm);
    v.Field("board_aim_mm", g.board_aim_mm);
    v.Field("incidence_deg", g.incidence_deg);
    v.Field("mount_tilt_deg", g.mount_tilt_deg);
  });
  v.Group("beams", [&] {
    auto& b = o.beams;
    v.Field("count", b.count);
    v.Field("spanning_angle_deg", b.spanning_angle_deg);
    v.Field("fan_fractions", b.fan_fractions);
    v.Field("offsets_mm", b.offsets_mm);
    v.Field("validate_ids", b.validate_ids);
    v.Field("source_distance_mm", b.source_distance_mm);
  });
  v.Group("world_board", [&] { VisitBoard(v, o.world_board); });
  v.Group("sliding_board", [&] { VisitBoard(v, o.sliding_board); });
  v.Group("camera", [&] {
    auto& c = o.camera;
    v.Field("width", c.width);
    v.Field("height", c.height);
    v.Field("fx", c.fx);
    v.Field("fy", c.fy);
    v.Field("cx", c.cx);
    v.Field("cy", c.cy);
    v.Field("distortion", c.distortion);
    v.Field("c1_centre_mm", c.c1_centre_mm);
    v.Field("c1_target_mm", c.c1_target_mm);
    v.Field("c2_centre_mm", c.c2_centre_mm);
    v.Field("c2_target_mm", c.c2_target_mm);
  });
  v.Group("step1", [&] {
    auto& s = o.step1;
    v.Field("poses", s.poses);
    v.Field("nearest_mm", s.nearest_mm);
    v.Field("farthest_mm", s.farthest_mm);
    v.Field("tilt_deg", s.tilt_deg);
    v.Field("identification_frames", s.identification_frames);
    v.Field("background_frames", s.background_frames);
    v.Field("exposures", s.exposures);
  });
  v.Group("step2", [&] {
    auto& s = o.step2;
    v.Field("neutral_frames", s.neutral_frames);
    v.Field("fast_only_frames", s.fast_only_frames);
    v.Field("fast_only_triggers_per_frame", s.fast_only_triggers_per_frame);
    v.Field("scan_triggers_per_frame", s.scan_triggers_per_frame);
  });
  v.Group("triggers", [&] {
    auto& t = o.triggers;
    v.Field("candidates", t.candidates);
    v.Field("max_triggers", t.max_triggers);
    v.Field("min_separation_px", t.min_separation_px);
    v.Field("board_margin_mm", t.board_margin_mm);
  });
  v.Group("hall", [&] {
    auto& h = o.hall;
    v.Field("sample_rate_hz", h.sample_rate_hz);
    v.Field("background_duration_s", h.background_duration_s);
    v.Field("actual_duration_s", h.actual_duration_s);
    v.Field("magnet_position_mm", h.magnet_position_mm);
    v.Field("magnet_direction", h.magnet_direction);
    v.Field("magnet_moment_am2", h.magnet_moment_am2);
    v.Field("sensor_position_mm", h.sensor_position_mm);
    v.Field("sensor_rotation_deg", h.sensor_rotation_deg);
    v.Field("earth_uT", h.earth_uT);
    v.Field("coil_fast_uT", h.coil_fast_uT);
    v.Field("coil_slow_uT", h.coil_slow_uT);
    v.Field("coil_harmonic2_ratio", h.coil_harmonic2_ratio);
    v.Field("background_shift_uT", h.background_shift_uT);
    v.Field("noise_uT", h.noise_uT);
    v.Field("delta_t_s", h.delta_t_s);
    v.Field("mcu_offset_us", h.mcu_offset_us);
    v.Field("mcu_rate_error_ppm", h.mcu_rate_error_ppm);
    v.Field("background_start_s", h.background_start_s);
    v.Field("actual_start_s", h.actual_start_s);
  });
  v.Group("render", [&] {
    v.Field("dot_sigma_mm", o.render.dot_sigma_mm);
    v.Field("dot_peak", o.render.dot_peak);
    v.Field("noise_sigma", o.render.noise_sigma);
    v.Field("shot_noise", o.render.shot_noise);
    v.Field("colour", o.render.colour);
  });
  v.Field("marg", o.marg);
}

std::string Where(const std::string& source, const YAML::Node& node, const std::string& key) {
  return common::YamlWhere(source, node) + ": " + key;
}

class Parser {
 public:
  Parser(const YAML::Node& root, std::string source) : source_(std::move(source)) {
    stack_.push_back({root, "", {}});
  }

  template <typename T>
  void Field(const char* key, T& value) {
    Frame& f = stack_.back();
    f.seen.insert(key);
    const YAML::Node child = f.node[key];
    if (!child) return;
    const std::string path = f.prefix + key;
    try {
      Read(child, value, path);
    } catch (const YAML::Exception& e) {
      throw std::runtime_error(Where(source_, child, path) + ": bad value (" + e.msg + ")");
    }
  }

  void Group(const char* key, const std::function<void()>& body) {
    Frame& f = stack_.back();
    f.seen.insert(key);
    const YAML::Node child = f.node[key];
    if (!child) return;
    if (!child.IsMap()) {
      throw std::runtime_error(Where(source_, child, f.prefix + key) + ": expected a mapping");
    }
    stack_.push_back({child, f.prefix + key + ".", {}});
    body();
    CheckUnknown();
    stack_.pop_back();
  }

  void CheckUnknown() {
    const Frame& f = stack_.back();
    for (const auto& kv : f.node) {
      if (!kv.first.IsScalar()) {
        throw std::runtime_error(Where(source_, kv.first, f.prefix + "?") +
                                 ": a key must be a name");
      }
      const std::string k = kv.first.as<std::string>();
      if (!f.seen.count(k)) {
        throw std::runtime_error(Where(source_, kv.first, f.prefix + k) + ": unknown key");
      }
    }
  }

 private:
  struct Frame {
    YAML::Node node;
    std::string prefix;
    std::set<std::string> seen;
  };

  template <typename T>
  void Read(const YAML::Node& n, T& value, const std::string& path) {
    value = n.as<T>();
  }
  template <typename T, size_t N>
  void Read(const YAML::Node& n, std::array<T, N>& value, const std::string& path) {
    if (!n.IsSequence() || n.size() != N) {
      throw std::runtime_error(Where(source_, n, path) + ": expected a list of " +
                               std::to_string(N) + " numbers");
    }
    for (size_t i = 0; i < N; ++i) value[i] = n[i].as<T>();
  }
  template <typename T>
  void Read(const YAML::Node& n, std::vector<T>& value, const std::string& path) {
    if (!n.IsSequence()) throw std::runtime_error(Where(source_, n, path) + ": expected a list");
    value.clear();
    for (size_t i = 0; i < n.size(); ++i) {
      T x{};
      Read(n[i], x, path);
      value.push_back(x);
    }
  }

  std::string source_;
  std::vector<Frame> stack_;
};

std::string Num(double x) { return common::YamlDouble(x); }

// Emits block-style YAML with flow lists; numbers in shortest round-trip form.
class Emitter {
 public:
  void Field(const char* key, double v) { Line(key, Num(v)); }
  void Field(const char* key, int v) { Line(key, std::to_string(v)); }
  void Field(const char* key, int64_t v) { Line(key, std::to_string(v)); }
  void Field(const char* key, uint64_t v) { Line(key, std::to_string(v)); }
  void Field(const char* key, bool v) { Line(key, v ? "true" : "false"); }
  template <typename T, size_t N>
  void Field(const char* key, const std::array<T, N>& v) {
    Line(key, List(v));
  }
  template <typename T>
  void Field(const char* key, const std::vector<T>& v) {
    std::string s = "[";
    for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + Item(v[i]);
    Line(key, s + "]");
  }
  void Group(const char* key, const std::function<void()>& body) {
    out_ << std::string(indent_, ' ') << key << ":\n";
    indent_ += 2;
    body();
    indent_ -= 2;
  }
  std::string str() const { return out_.str(); }

 private:
  static std::string Item(double x) { return Num(x); }
  static std::string Item(int x) { return std::to_string(x); }
  template <typename T, size_t N>
  static std::string Item(const std::array<T, N>& v) {
    return List(v);
  }
  template <typename T, size_t N>
  static std::string List(const std::array<T, N>& v) {
    std::string s = "[";
    for (size_t i = 0; i < N; ++i) s += (i ? ", " : "") + Item(v[i]);
    return s + "]";
  }
  void Line(const char* key, const std::string& value) {
    out_ << std::string(indent_, ' ') << key << ": " << value << "\n";
  }
  std::ostringstream out_;
  int indent_ = 0;
};

std::string Bad(const std::string& field, double value, const std::string& constraint) {
  return "Invalid simulation config: " + field + " = " + Num(value) +
         ". Violated constraint: " + constraint;
}

constexpr double kMaxFrequencyHz = 30e6;

// 0 for a frequency outside (0, kMaxFrequencyHz]: llround of an out-of-range value is
// unspecified and std::gcd of LLONG_MIN undefined (fuzz finding 6, docs/fuzzing.md).
long long Millihertz(double f) {
  return f > 0 && f <= kMaxFrequencyHz ? std::llround(f * 1000.0) : 0;
}

}  // namespace

double SimOptions::PatternPeriodS() const {
  const long long a = Millihertz(mirror.fast.frequency_hz);
  const long long b = Millihertz(mirror.slow.frequency_hz);
  const long long g = std::gcd(a, b);
  return g > 0 ? 1000.0 / static_cast<double>(g) : 0.0;
}

std::string SimOptions::Validate() const {
  for (const auto& [name, a] :
       {std::pair<std::string, const AxisOptions*>{"mirror.fast", &mirror.fast},
        {"mirror.slow", &mirror.slow}}) {
    // Upper bound: the 33520B's sine limit, and it keeps the mHz count inside a long long.
    if (!(a->frequency_hz > 0 && a->frequency_hz <= kMaxFrequencyHz))
      return Bad(name + ".frequency_hz", a->frequency_hz, "in (0, 30e6] (the 33520B's sine range)");
    if (std::abs(a->frequency_hz * 1000 - std::round(a->frequency_hz * 1000)) > 1e-6)
      return Bad(name + ".frequency_hz", a->frequency_hz, "a whole number of mHz");
    if (!(a->amplitude_vpp >= 0)) return Bad(name + ".amplitude_vpp", a->amplitude_vpp, ">= 0");
    if (!(a->resonance_hz > 0)) return Bad(name + ".resonance_hz", a->resonance_hz, "> 0");
    if (!(a->q > 0)) return Bad(name + ".q", a->q, "> 0");
    if (!(a->harmonic2_ratio >= 0 && a->harmonic2_ratio < 0.5))
      return Bad(name + ".harmonic2_ratio", a->harmonic2_ratio, "in [0, 0.5)");
  }
  const double period = PatternPeriodS();
  if (!(period > 0 && period <= 10.0))
    return Bad("pattern period 1/gcd(f_fast, f_slow) [s]", period, "in (0, 10]");
  if (!(geometry.mirror_distance_mm > 20))
    return Bad("geometry.mirror_distance_mm", geometry.mirror_distance_mm, "> 20");
  if (!(geometry.incidence_deg > 5 && geometry.incidence_deg < 80))
    return Bad("geometry.incidence_deg", geometry.incidence_deg, "in (5, 80)");
  if (beams.count < 2) return Bad("beams.count", beams.count, ">= 2");
  if (static_cast<int>(beams.fan_fractions.size()) != beams.count)
    return Bad("beams.fan_fractions (size)", static_cast<double>(beams.fan_fractions.size()),
               "== beams.count");
  if (static_cast<int>(beams.offsets_mm.size()) != beams.count)
    return Bad("beams.offsets_mm (size)", static_cast<double>(beams.offsets_mm.size()),
               "== beams.count");
  for (double f : beams.fan_fractions)
    if (!(f >= -0.5 && f <= 0.5)) return Bad("beams.fan_fractions[]", f, "in [-0.5, 0.5]");
  for (int id : beams.validate_ids)
    if (id < 1 || id > beams.count) return Bad("beams.validate_ids[]", id, "in [1, beams.count]");
  if (static_cast<int>(beams.validate_ids.size()) > beams.count - 2)
    return Bad("beams.validate_ids (size)", static_cast<double>(beams.validate_ids.size()),
               "leaves at least 2 estimate beams");
  if (!(beams.spanning_angle_deg > 1 && beams.spanning_angle_deg < 120))
    return Bad("beams.spanning_angle_deg", beams.spanning_angle_deg, "in (1, 120)");
  if (!(beams.source_distance_mm > step1.farthest_mm))
    return Bad("beams.source_distance_mm", beams.source_distance_mm, "> step1.farthest_mm");
  for (const auto& [name, b] :
       {std::pair<std::string, const BoardOptions*>{"world_board", &world_board},
        {"sliding_board", &sliding_board}}) {
    if (b->cols < 3 || b->cols % 2 == 0)
      return Bad(name + ".cols", b->cols, "odd and >= 3 ((cols+1) even)");
    if (b->rows < 2 || b->rows % 2 == 1)
      return Bad(name + ".rows", b->rows, "even and >= 2 ((rows+1) odd)");
    if (!(b->square_mm > 0)) return Bad(name + ".square_mm", b->square_mm, "> 0");
  }
  if (camera.width < 64 || camera.height < 64)
    return Bad("camera.width/height", std::min(camera.width, camera.height), ">= 64");
  if (!(camera.fx > 0 && camera.fy > 0))
    return Bad("camera.fx/fy", std::min(camera.fx, camera.fy), "> 0");
  if (step1.poses < 2) return Bad("step1.poses", step1.poses, ">= 2");
  if (step1.exposures < 1 || step1.exposures > 16)
    return Bad("step1.exposures", step1.exposures, "in [1, 16]");
  if (!(step1.nearest_mm > 0 && step1.farthest_mm > step1.nearest_mm))
    return Bad("step1.farthest_mm", step1.farthest_mm, "> step1.nearest_mm > 0");
  if (step2.neutral_frames < 1) return Bad("step2.neutral_frames", step2.neutral_frames, ">= 1");
  if (step2.fast_only_frames < 1)
    return Bad("step2.fast_only_frames", step2.fast_only_frames, ">= 1");
  if (step2.fast_only_triggers_per_frame < 1)
    return Bad("step2.fast_only_triggers_per_frame", step2.fast_only_triggers_per_frame, ">= 1");
  if (step2.scan_triggers_per_frame < 1)
    return Bad("step2.scan_triggers_per_frame", step2.scan_triggers_per_frame, ">= 1");
  if (triggers.candidates < 1) return Bad("triggers.candidates", triggers.candidates, ">= 1");
  if (triggers.max_triggers < 3) return Bad("triggers.max_triggers", triggers.max_triggers, ">= 3");
  if (!(triggers.min_separation_px >= 0))
    return Bad("triggers.min_separation_px", triggers.min_separation_px, ">= 0");
  if (!(hall.sample_rate_hz > 0 && hall.sample_rate_hz <= 100000))
    return Bad("hall.sample_rate_hz", hall.sample_rate_hz, "in (0, 1e5]");
  if (!(hall.background_duration_s >= 2 * period))
    return Bad("hall.background_duration_s", hall.background_duration_s, ">= 2 pattern periods");
  if (!(hall.actual_duration_s >= 2 * period))
    return Bad("hall.actual_duration_s", hall.actual_duration_s, ">= 2 pattern periods");
  if (!(hall.noise_uT >= 0)) return Bad("hall.noise_uT", hall.noise_uT, ">= 0");
  if (!(std::abs(hall.mcu_rate_error_ppm) < 1000))
    return Bad("hall.mcu_rate_error_ppm", hall.mcu_rate_error_ppm, "|x| < 1000");
  if (!(hall.background_start_s >= 0 && hall.actual_start_s >= 0))
    return Bad("hall.background_start_s/actual_start_s",
               std::min(hall.background_start_s, hall.actual_start_s), ">= 0");
  const double sensor_dist = std::hypot(hall.sensor_position_mm[0] - hall.magnet_position_mm[0],
                                        hall.sensor_position_mm[1] - hall.magnet_position_mm[1],
                                        hall.sensor_position_mm[2] - hall.magnet_position_mm[2]);
  if (!(sensor_dist > 1.0))
    return Bad("|hall.sensor_position_mm - hall.magnet_position_mm|", sensor_dist, "> 1 mm");
  if (!(render.dot_sigma_mm > 0)) return Bad("render.dot_sigma_mm", render.dot_sigma_mm, "> 0");
  if (!(render.dot_peak > 0 && render.dot_peak <= 2))
    return Bad("render.dot_peak", render.dot_peak, "in (0, 2]");
  if (!(render.shot_noise >= 0)) return Bad("render.shot_noise", render.shot_noise, ">= 0");
  if (!(render.noise_sigma >= 0)) return Bad("render.noise_sigma", render.noise_sigma, ">= 0");
  return "";
}

SimOptions ParseSimOptions(const std::string& yaml_text, const std::string& source_name) {
  const YAML::Node root = common::YamlFields(source_name).Load(yaml_text);
  SimOptions options;
  if (root.IsNull()) return options;
  if (!root.IsMap())
    throw std::runtime_error(source_name + ": expected a mapping at the top level");
  Parser parser(root, source_name);
  VisitAll(parser, options);
  parser.CheckUnknown();
  if (const std::string err = options.Validate(); !err.empty()) {
    throw std::runtime_error(source_name + ": " + err);
  }
  return options;
}

SimOptions LoadSimOptions(const std::filesystem::path& file) {
  return ParseSimOptions(common::ReadFileText(file, "cannot open simulation config"),
                         file.string());
}

std::string SimOptionsToYaml(const SimOptions& options) {
  Emitter emitter;
  SimOptions copy = options;
  VisitAll(emitter, copy);
  return emitter.str();
}

}  // namespace msmcal::sim
