#include "common/yaml_fields.h"

#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <utility>

#include "common/text_io.h"

namespace msmcal::common {
namespace {

std::string ScalarText(const YAML::Node& n) { return n.IsScalar() ? n.Scalar() : ""; }

}  // namespace

int YamlLine(const YAML::Node& node) {
  if (!node.IsDefined()) return 0;
  const YAML::Mark m = node.Mark();
  return m.is_null() || m.line < 0 ? 0 : m.line + 1;
}

std::string YamlWhere(const std::string& origin, const YAML::Node& node) {
  const int line = YamlLine(node);
  return line > 0 ? origin + ":" + std::to_string(line) : origin;
}

std::string FieldNumber(double v) {
  if (std::abs(v) < 1e15 && v == std::floor(v)) return std::to_string(static_cast<int64_t>(v));
  return ShortestDouble(v);
}

namespace {

// Whether the scalar `n` converts to T.
template <typename T>
bool ReadsAs(const YAML::Node& n) {
  if (!n.IsScalar()) return false;
  try {
    (void)n.as<T>();
    return true;
  } catch (const YAML::Exception&) {
    return false;
  }
}

}  // namespace

bool IsYamlNumber(const YAML::Node& n) { return ReadsAs<double>(n); }
bool IsYamlBool(const YAML::Node& n) { return ReadsAs<bool>(n); }

YamlFields::YamlFields(std::string origin, Raise raise)
    : origin_(std::move(origin)), raise_(std::move(raise)) {}

void YamlFields::Throw(const std::string& message) const {
  if (raise_) raise_(message);
  throw std::runtime_error(message);
}

YAML::Node YamlFields::Load(const std::string& text, const std::string& prefix) const {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    const std::string where = e.mark.is_null() || e.mark.line < 0
                                  ? origin_
                                  : origin_ + ":" + std::to_string(e.mark.line + 1);
    Throw(where + ": " + prefix + e.msg);
  }
}

void YamlFields::Fail(const YAML::Node& at, const std::string& key,
                      const std::string& problem) const {
  Throw(YamlWhere(origin_, at) + ": " + key + ": " + problem);
}

void YamlFields::FailText(const YAML::Node& at, const std::string& text) const {
  Throw(YamlWhere(origin_, at) + ": " + text);
}

YAML::Node YamlFields::Child(const YAML::Node& parent, const std::string& key) const {
  if (!parent || !parent.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
  return parent[key];
}

YAML::Node YamlFields::Required(const YAML::Node& parent, const std::string& key,
                                const std::string& path) const {
  const YAML::Node n = Child(parent, key);
  if (!n) Fail(parent, path, "missing");
  return n;
}

void YamlFields::CheckKeys(const YAML::Node& map, const std::string& path,
                           const std::set<std::string>& allowed) const {
  if (!map.IsMap()) Fail(map, path, "must be a mapping");
  for (const auto& kv : map) {
    const std::string k = KeyAt(kv.first, path);
    if (!allowed.count(k)) Fail(kv.first, path + "." + k, "unknown key");
  }
}

std::string YamlFields::KeyAt(const YAML::Node& key, const std::string& path) const {
  if (!key.IsScalar()) Fail(key, path.empty() ? "(root)" : path, "a key must be a plain name");
  return key.Scalar();
}

YAML::Node YamlFields::Map(const YAML::Node& parent, const std::string& key,
                           const std::string& path, const std::set<std::string>& allowed,
                           bool optional) const {
  const YAML::Node n = Child(parent, key);
  if (!n) {
    if (optional) return YAML::Node();
    Fail(parent, path, "missing");
  }
  CheckKeys(n, path, allowed);
  return n;
}

double YamlFields::NumberAt(const YAML::Node& n, const std::string& path,
                            const NumberRule& rule) const {
  const std::string text = ScalarText(n);
  double v = 0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    Fail(n, path, "must be a number, got '" + text + "'");
  }
  if (std::isnan(v) || (std::isinf(v) && !rule.allow_infinite)) {
    FailText(n, path + " = " + text + ": must be a finite number" +
                    (rule.non_finite_note.empty() ? "" : " " + rule.non_finite_note));
  }
  if (std::isfinite(v) && ((rule.lo_open ? !(v > rule.lo) : !(v >= rule.lo)) || !(v <= rule.hi))) {
    FailText(n, path + " = " + FieldNumber(v) + ": must be in " + (rule.lo_open ? "(" : "[") +
                    FieldNumber(rule.lo) + ", " + FieldNumber(rule.hi) + "]");
  }
  return v;
}

int YamlFields::IntAt(const YAML::Node& n, const std::string& path, int lo, int hi) const {
  int v = 0;
  try {
    v = n.as<int>();
  } catch (const YAML::Exception&) {
    Fail(n, path, "must be an integer, got '" + ScalarText(n) + "'");
  }
  if (v < lo || v > hi) {
    FailText(n, path + " = " + std::to_string(v) + ": must be in [" + std::to_string(lo) + ", " +
                    std::to_string(hi) + "]");
  }
  return v;
}

bool YamlFields::BoolAt(const YAML::Node& n, const std::string& path) const {
  try {
    return n.as<bool>();
  } catch (const YAML::Exception&) {
    Fail(n, path, "must be true or false, got '" + ScalarText(n) + "'");
  }
}

std::string YamlFields::StringAt(const YAML::Node& n, const std::string& path,
                                 bool non_empty) const {
  if (non_empty && (!n.IsScalar() || n.Scalar().empty())) {
    Fail(n, path, "must be a non-empty string");
  }
  if (!n.IsScalar()) Fail(n, path, "must be a string");
  return n.Scalar();
}

double YamlFields::Number(const YAML::Node& parent, const std::string& key, const std::string& path,
                          std::optional<double> def, const NumberRule& rule) const {
  const YAML::Node n = Child(parent, key);
  if (!n) {
    if (def) return *def;
    Fail(parent, path, "missing");
  }
  return NumberAt(n, path, rule);
}

int YamlFields::Int(const YAML::Node& parent, const std::string& key, const std::string& path,
                    std::optional<int> def, int lo, int hi) const {
  const YAML::Node n = Child(parent, key);
  if (!n) {
    if (def) return *def;
    Fail(parent, path, "missing");
  }
  return IntAt(n, path, lo, hi);
}

bool YamlFields::Bool(const YAML::Node& parent, const std::string& key, const std::string& path,
                      std::optional<bool> def) const {
  const YAML::Node n = Child(parent, key);
  if (!n) {
    if (def) return *def;
    Fail(parent, path, "missing");
  }
  return BoolAt(n, path);
}

std::string YamlFields::String(const YAML::Node& parent, const std::string& key,
                               const std::string& path, std::optional<std::string> def,
                               bool non_empty) const {
  const YAML::Node n = Child(parent, key);
  if (!n) {
    if (def) return *def;
    Fail(parent, path, "missing");
  }
  return StringAt(n, path, non_empty);
}

}  // namespace msmcal::common
