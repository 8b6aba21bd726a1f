#include "sessions/sweep/sweep_plan.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "common/yaml_fields.h"

namespace msmcal::sweep {
namespace {

namespace fs = std::filesystem;

constexpr const char* kRepeatsKey = "repeats";
constexpr size_t kMaxPoints = 10000;
constexpr int kMaxRepeats = 1000;
constexpr size_t kMaxFolderName = 120;

// "<source>:<line>: <what>" (common/yaml_fields.h).
[[noreturn]] void Fail(const std::string& source, const YAML::Node& at, const std::string& what) {
  common::YamlFields(source).FailText(at, what);
}

std::vector<std::string> SplitPath(const std::string& path) {
  std::vector<std::string> parts;
  std::string cur;
  for (char c : path) {
    if (c == '.') {
      parts.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  parts.push_back(cur);
  return parts;
}

// The node at `parts` under `root` (undefined when absent). Const access only: creates nothing.
YAML::Node Lookup(const YAML::Node& root, const std::vector<std::string>& parts) {
  YAML::Node cur = YAML::Clone(root);
  for (const auto& p : parts) {
    if (!cur.IsMap() || !cur[p]) return YAML::Node(YAML::NodeType::Undefined);
    const YAML::Node next = cur[p];
    cur.reset(next);
  }
  return cur;
}

// Sets root[parts...] = value (recursion so that yaml-cpp's handle assignment never overwrites
// a parent's content).
void SetPath(YAML::Node node, const std::vector<std::string>& parts, size_t i,
             const YAML::Node& value) {
  if (i + 1 == parts.size()) {
    node[parts[i]] = YAML::Clone(value);
    return;
  }
  SetPath(node[parts[i]], parts, i + 1, value);
}

// Checks that `value` has the form of the schema leaf `schema` (number, bool, list of numbers,
// list of lists); names the key and the expected form.
void CheckLeaf(const std::string& source, const std::string& key, const YAML::Node& schema,
               const YAML::Node& value) {
  if (schema.IsScalar()) {
    const std::string s = schema.Scalar();
    if (s == "true" || s == "false") {
      if (!common::IsYamlBool(value)) Fail(source, value, key + ": expected true or false");
    } else if (common::IsYamlNumber(schema)) {
      if (!common::IsYamlNumber(value)) Fail(source, value, key + ": expected a number");
    } else if (!value.IsScalar() || value.Scalar() != s) {
      // A text field (a rig file's host, camera kind, channel role) is not a sweep option; the
      // plan's self-contained copy (SweepPlanToYaml) carries it with its default value.
      Fail(source, value, key + ": a text field, not varied by a sweep (its value is '" + s + "')");
    }
    return;
  }
  if (schema.IsSequence()) {
    if (!value.IsSequence()) Fail(source, value, key + ": expected a list");
    const bool nested = schema.size() > 0 && schema[0].IsSequence();
    for (const auto& e : value) {
      if (nested) {
        if (!e.IsSequence()) Fail(source, e, key + ": expected a list of lists of numbers");
        for (const auto& x : e)
          if (!common::IsYamlNumber(x)) Fail(source, x, key + ": expected numbers");
      } else if (!common::IsYamlNumber(e)) {
        Fail(source, e, key + ": expected a list of numbers");
      }
    }
  }
}

// Lays `over` (the plan's base:) onto `tree`, checking keys and value forms against `schema`.
void Overlay(const std::string& source, const std::string& noun, const std::string& prefix,
             const YAML::Node& schema, YAML::Node tree, const YAML::Node& over) {
  if (!over.IsMap())
    Fail(source, over, (prefix.empty() ? std::string("base") : prefix) + ": expected a mapping");
  for (const auto& kv : over) {
    const std::string key =
        common::YamlFields(source).KeyAt(kv.first, prefix.empty() ? "base" : "base." + prefix);
    const std::string full = prefix.empty() ? key : prefix + "." + key;
    const YAML::Node s = schema[key];
    if (!s) Fail(source, kv.first, "base." + full + ": unknown " + noun);
    if (s.IsMap()) {
      Overlay(source, noun, full, s, tree[key], kv.second);
    } else {
      CheckLeaf(source, "base." + full, s, kv.second);
      tree[key] = YAML::Clone(kv.second);
    }
  }
}

std::string FlowText(const YAML::Node& n) {
  YAML::Emitter e;
  e.SetSeqFormat(YAML::Flow);
  e.SetMapFormat(YAML::Flow);
  e << n;
  return e.c_str();
}

std::string ReadFile(const fs::path& file, const std::string& what) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot open " + what);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string Sanitise(const std::string& s) {
  std::string out;
  for (char c : s) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '=' || c == '+' || c == '-';
    out += ok ? c : '_';
  }
  return out;
}

// "[110, 135]" -> "110_135" for folder names.
std::string CompactValue(const std::string& v) {
  std::string out;
  for (char c : v) {
    if (c == '[' || c == ']' || c == ' ') continue;
    out += c == ',' ? '_' : c;
  }
  return out;
}

}  // namespace

std::string SweepPoint::Label() const {
  std::string s;
  for (const auto& [path, value] : values) s += ShortAxisName(path) + "=" + value + " ";
  return s + "r" + std::to_string(repeat);
}

std::string ShortAxisName(const std::string& path) {
  const auto parts = SplitPath(path);
  if (parts.size() < 2) return path;
  return parts[parts.size() - 2] + "." + parts.back();
}

std::string PointFolderName(size_t index, int repeat,
                            const std::vector<std::pair<std::string, std::string>>& values) {
  char prefix[32];
  std::snprintf(prefix, sizeof prefix, "p%03zu", index + 1);
  std::string name = prefix;
  for (const auto& [path, value] : values)
    name += "-" + Sanitise(ShortAxisName(path) + "=" + CompactValue(value));
  const std::string tail = "-r" + std::to_string(repeat);
  if (name.size() + tail.size() > kMaxFolderName) name.resize(kMaxFolderName - tail.size());
  return name + tail;
}

SweepPlan ParseSweepPlan(const std::string& yaml_text, const std::string& source_name,
                         const fs::path& base_dir,
                         std::shared_ptr<const SweepParameters> parameters) {
  if (!parameters) throw std::invalid_argument("ParseSweepPlan: no SweepParameters");
  const SweepParameters& params = *parameters;
  const std::string noun = params.Noun();
  const YAML::Node root = common::YamlFields(source_name).Load(yaml_text);
  if (!root.IsMap())
    throw std::runtime_error(source_name + ": expected a mapping at the top level");
  static const std::set<std::string> kKeys = {"base_config", "base",  "axes",
                                              kRepeatsKey,   "order", "note"};
  for (const auto& kv : root) {
    const std::string key = common::YamlFields(source_name).KeyAt(kv.first, "(top level)");
    if (!kKeys.count(key))
      Fail(source_name, kv.first,
           "unknown key '" + key + "' (allowed: base_config, base, axes, repeats, order, note)");
  }
  SweepPlan plan;
  plan.source = source_name;
  plan.parameters = parameters;

  // Base options: defaults < base_config < base:.
  const YAML::Node schema = YAML::Load(params.DefaultsYaml());
  std::string base_options = params.DefaultsYaml();
  if (const YAML::Node bc = root["base_config"]) {
    if (!bc.IsScalar()) Fail(source_name, bc, "base_config: expected a file name");
    fs::path file = bc.as<std::string>();
    if (file.is_relative()) file = base_dir / file;
    try {
      base_options = params.LoadFile(file);
    } catch (const std::exception& e) {
      Fail(source_name, bc, std::string("base_config: ") + e.what());
    }
  }
  YAML::Node tree = YAML::Load(base_options);
  if (const YAML::Node base = root["base"]) {
    if (!base.IsNull()) Overlay(source_name, noun, "", schema, tree, base);
  }
  try {
    uint64_t seed = 0;
    plan.base_yaml = params.Resolve(YAML::Dump(tree), "base", /*repeat=*/0, &seed);
  } catch (const std::exception& e) {
    Fail(source_name, root["base"] ? root["base"] : root, e.what());
  }

  // Axes (file order first).
  std::vector<SweepAxis> axes;
  if (const YAML::Node ax = root["axes"]) {
    if (!ax.IsMap()) Fail(source_name, ax, "axes: expected a mapping from option paths to lists");
    for (const auto& kv : ax) {
      SweepAxis axis;
      axis.path = common::YamlFields(source_name).KeyAt(kv.first, "axes");
      axis.line = common::YamlLine(kv.first);
      const YAML::Node s = Lookup(schema, SplitPath(axis.path));
      if (!s.IsDefined() || s.IsMap())
        Fail(source_name, kv.first,
             "axes." + axis.path + ": unknown " + noun + " " + params.PathHint());
      for (const auto& a : axes)
        if (a.path == axis.path)
          Fail(source_name, kv.first, "axes." + axis.path + ": listed twice");
      if (!kv.second.IsSequence() || kv.second.size() == 0)
        Fail(source_name, kv.second, "axes." + axis.path + ": expected a non-empty list of values");
      std::set<std::string> seen;
      for (const auto& v : kv.second) {
        CheckLeaf(source_name, "axes." + axis.path, s, v);
        const std::string text = FlowText(v);
        if (!seen.insert(text).second)
          Fail(source_name, v, "axes." + axis.path + ": value " + text + " listed twice");
        axis.values.push_back(text);
      }
      axes.push_back(axis);
    }
  }

  if (const YAML::Node r = root[kRepeatsKey]) {
    int n = 0;
    try {
      n = r.as<int>();
    } catch (const YAML::Exception&) {
      Fail(source_name, r, "repeats: expected an integer");
    }
    if (n < 1 || n > kMaxRepeats)
      Fail(source_name, r,
           "repeats: " + std::to_string(n) + " out of range [1, " + std::to_string(kMaxRepeats) +
               "]");
    plan.repeats = n;
  }

  plan.repeat_level = axes.size();
  if (const YAML::Node order = root["order"]) {
    if (!order.IsSequence()) Fail(source_name, order, "order: expected a list of axis paths");
    std::vector<SweepAxis> ordered;
    bool repeats_seen = false;
    for (const auto& o : order) {
      const std::string name = o.IsScalar() ? o.as<std::string>() : std::string();
      if (name == kRepeatsKey) {
        if (repeats_seen) Fail(source_name, o, "order: 'repeats' listed twice");
        repeats_seen = true;
        plan.repeat_level = ordered.size();
        continue;
      }
      auto it = std::find_if(axes.begin(), axes.end(),
                             [&](const SweepAxis& a) { return a.path == name; });
      if (it == axes.end())
        Fail(source_name, o, "order: '" + name + "' is not an axis (nor 'repeats')");
      for (const auto& a : ordered)
        if (a.path == name) Fail(source_name, o, "order: '" + name + "' listed twice");
      ordered.push_back(*it);
    }
    if (ordered.size() != axes.size()) {
      for (const auto& a : axes) {
        const bool listed = std::any_of(ordered.begin(), ordered.end(),
                                        [&](const SweepAxis& b) { return b.path == a.path; });
        if (!listed) Fail(source_name, order, "order: axis '" + a.path + "' missing");
      }
    }
    if (!repeats_seen) plan.repeat_level = ordered.size();
    axes = ordered;
  }
  plan.axes = axes;

  size_t total = static_cast<size_t>(plan.repeats);
  for (const auto& a : plan.axes) {
    total *= a.values.size();
    if (total > kMaxPoints)
      Fail(source_name, root["axes"],
           "axes: more than " + std::to_string(kMaxPoints) + " points (x repeats)");
  }

  if (const YAML::Node n = root["note"]) {
    if (!n.IsScalar()) Fail(source_name, n, "note: expected text");
    plan.note = n.as<std::string>();
    // A CR that YAML did not take as part of a line end (a CRLF file's last line without its
    // LF) is the line end; any other control character would not survive the plan's copy
    // (YAML writes it bare, and reading it back breaks the line there: fuzz/sweep_yaml).
    while (!plan.note.empty() && plan.note.back() == '\r') plan.note.pop_back();
    // And UTF-8: yaml-cpp writes other bytes back as something else. One pass: each character's
    // length from its lead byte, its continuation bytes, then control characters (C0, DEL, C1).
    for (size_t i = 0; i < plan.note.size();) {
      const unsigned char c = static_cast<unsigned char>(plan.note[i]);
      const size_t len = c < 0x80                 ? 1
                         : c >= 0xC2 && c <= 0xDF ? 2
                         : c >= 0xE0 && c <= 0xEF ? 3
                         : c >= 0xF0 && c <= 0xF4 ? 4
                                                  : 0;
      bool utf8 = len > 0 && i + len <= plan.note.size();
      for (size_t k = 1; utf8 && k < len; ++k)
        utf8 = (static_cast<unsigned char>(plan.note[i + k]) & 0xC0) == 0x80;
      if (!utf8)
        Fail(source_name, n,
             "note: not UTF-8 text at byte " + std::to_string(i + 1) +
                 " (a note is text: letters, tabs and line breaks)");
      const unsigned code = len == 1   ? c
                            : len == 2 ? (c & 0x1Fu) << 6 | (plan.note[i + 1] & 0x3F)
                                       : 0;
      if ((code < 0x20 && len == 1 && c != '\n' && c != '\t') || (code >= 0x7F && code < 0xA0)) {
        char hex[8];
        std::snprintf(hex, sizeof hex, "0x%02x", code);
        Fail(source_name, n,
             "note: control character " + std::string(hex) + " at byte " + std::to_string(i + 1) +
                 " (a note is text: letters, tabs and line breaks)");
      }
      i += len;
    }
  }
  (void)ExpandPoints(plan);  // every point's options valid, or the error names the axis
  return plan;
}

SweepPlan LoadSweepPlan(const fs::path& file, std::shared_ptr<const SweepParameters> parameters) {
  return ParseSweepPlan(ReadFile(file, "sweep plan"), file.string(), file.parent_path(),
                        std::move(parameters));
}

std::vector<SweepPoint> ExpandPoints(const SweepPlan& plan) {
  if (!plan.parameters)
    throw std::invalid_argument("ExpandPoints: the plan has no SweepParameters");
  // Loop levels outermost first: axis indices, with -1 for the repeat loop.
  std::vector<int> levels;
  for (size_t i = 0; i <= plan.axes.size(); ++i) {
    if (i == plan.repeat_level) levels.push_back(-1);
    if (i < plan.axes.size()) levels.push_back(static_cast<int>(i));
  }
  auto level_size = [&](int l) {
    return l < 0 ? static_cast<size_t>(plan.repeats)
                 : plan.axes[static_cast<size_t>(l)].values.size();
  };
  const YAML::Node base = YAML::Load(plan.base_yaml);
  std::vector<size_t> counter(levels.size(), 0);
  std::vector<SweepPoint> points;
  for (bool done = false; !done;) {
    SweepPoint p;
    p.index = points.size();
    std::vector<size_t> value_index(plan.axes.size(), 0);
    for (size_t k = 0; k < levels.size(); ++k) {
      if (levels[k] < 0)
        p.repeat = static_cast<int>(counter[k]);
      else
        value_index[static_cast<size_t>(levels[k])] = counter[k];
    }
    YAML::Node tree = YAML::Clone(base);
    std::string where;
    for (size_t a = 0; a < plan.axes.size(); ++a) {
      const SweepAxis& axis = plan.axes[a];
      const std::string& v = axis.values[value_index[a]];
      p.values.emplace_back(axis.path, v);
      SetPath(tree, SplitPath(axis.path), 0, YAML::Load(v));
      where += (where.empty() ? "" : ", ") + axis.path + " = " + v;
    }
    try {
      p.options_yaml = plan.parameters->Resolve(
          YAML::Dump(tree), "point " + (where.empty() ? "base" : where), p.repeat, &p.seed);
    } catch (const std::exception& e) {
      const int line = plan.axes.empty() ? 0 : plan.axes.front().line;
      throw std::runtime_error(plan.source + (line > 0 ? ":" + std::to_string(line) : "") +
                               ": axes: " + e.what());
    }
    p.name = PointFolderName(p.index, p.repeat, p.values);
    points.push_back(std::move(p));
    // Odometer: the innermost level varies fastest.
    size_t k = levels.size();
    while (true) {
      if (k == 0) {
        done = true;
        break;
      }
      --k;
      if (++counter[k] < level_size(levels[k])) break;
      counter[k] = 0;
    }
  }
  return points;
}

std::string SweepPlanToYaml(const SweepPlan& plan) {
  YAML::Node root;
  if (!plan.note.empty()) root["note"] = plan.note;
  root[kRepeatsKey] = plan.repeats;
  YAML::Node order(YAML::NodeType::Sequence);
  for (size_t i = 0; i <= plan.axes.size(); ++i) {
    if (i == plan.repeat_level) order.push_back(kRepeatsKey);
    if (i < plan.axes.size()) order.push_back(plan.axes[i].path);
  }
  root["order"] = order;
  YAML::Node axes(YAML::NodeType::Map);
  for (const auto& a : plan.axes) {
    YAML::Node values(YAML::NodeType::Sequence);
    for (const auto& v : a.values) values.push_back(YAML::Load(v));
    values.SetStyle(YAML::EmitterStyle::Flow);
    axes[a.path] = values;
  }
  root["axes"] = axes;
  YAML::Node base = YAML::Load(plan.base_yaml);
  root["base"] = base;
  YAML::Emitter e;
  e << root;
  const std::string noun = plan.parameters ? plan.parameters->Noun() : "option";
  return "# msmcal sweep plan (self-contained copy of " + plan.source + ": base holds every " +
         noun + ")\n" + std::string(e.c_str()) + "\n";
}

std::string ComparePlans(const SweepPlan& stored, const SweepPlan& requested) {
  const auto a = ExpandPoints(stored);
  const auto b = ExpandPoints(requested);
  if (a.size() != b.size())
    return "the stored plan has " + std::to_string(a.size()) + " points, " + requested.source +
           " has " + std::to_string(b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].name != b[i].name)
      return "point " + std::to_string(i + 1) + " is " + a[i].name + " in the stored plan, " +
             b[i].name + " in " + requested.source;
    const std::string& ya = a[i].options_yaml;
    const std::string& yb = b[i].options_yaml;
    if (ya != yb) {
      std::istringstream sa(ya), sb(yb);
      std::string la, lb;
      while (std::getline(sa, la) && std::getline(sb, lb))
        if (la != lb) break;
      return "point " + a[i].name + ": " + requested.parameters->Noun() + "s differ (stored '" +
             la + "', " + requested.source + " '" + lb + "')";
    }
  }
  return "";
}

}  // namespace msmcal::sweep
