#pragma once
// One reader of YAML fields for every configuration and result file msmcal reads (rig files,
// simulator options, sweep plans, interchange and result files, the Hall MCU section): the
// message of a bad field is always
//
//   <origin>:<line>: <key>: <problem>         rig.yaml:17: generators.unit1.port: missing
//   <origin>:<line>: <key> = <value>: <rule>  rig.yaml:9: camera.fx = .nan: must be a finite number
//
// (":<line>" left out where the node has no position). `key` is the field's full path
// ("step2.frames[3].kind"). Bad input throws (house style 9: bad input fails at the boundary);
// by default std::runtime_error, or what the caller's `raise` throws (the interchange format's
// InterchangeError).
//
// Thread safety: a YamlFields is immutable after construction.

#include <yaml-cpp/yaml.h>

#include <functional>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <utility>

namespace msmcal::common {

// 1-based line of `node` in its document; 0 when it has none (undefined node, built in code).
int YamlLine(const YAML::Node& node);
// "<origin>:<line>", or "<origin>" when the node has no line.
std::string YamlWhere(const std::string& origin, const YAML::Node& node);

// Accepted numbers: finite, in [lo, hi] (lo excluded when lo_open). `allow_infinite` accepts
// .inf / -.inf (the range then applies to finite values only); `non_finite_note` follows the
// "must be a finite number" message ("(inf is accepted only for load_ohm: high impedance)").
//   NumberRule::In(0, 20), NumberRule::Above(0), NumberRule().Note("(...)")
struct NumberRule {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool allow_infinite = false;
  std::string non_finite_note;

  static NumberRule In(double lo, double hi) {
    NumberRule r;
    r.lo = lo;
    r.hi = hi;
    return r;
  }
  // (lo, hi]
  static NumberRule Above(double lo, double hi = std::numeric_limits<double>::infinity()) {
    NumberRule r = In(lo, hi);
    r.lo_open = true;
    return r;
  }
  NumberRule& AllowInfinite() {
    allow_infinite = true;
    return *this;
  }
  NumberRule& Note(std::string note) {
    non_finite_note = std::move(note);
    return *this;
  }
};

// Numbers in messages: whole numbers as integers ("200000", not "2e+05"), others shortest
// round-trip.
std::string FieldNumber(double v);

class YamlFields {
 public:
  // `raise` throws an exception carrying the message; empty: std::runtime_error.
  using Raise = std::function<void(const std::string& message)>;
  explicit YamlFields(std::string origin, Raise raise = {});

  const std::string& origin() const { return origin_; }

  // Parses a document; a syntax error as "<origin>:<line>: <yaml-cpp's message>" (`prefix`
  // before the yaml-cpp message, e.g. "YAML syntax error: ").
  YAML::Node Load(const std::string& text, const std::string& prefix = "") const;

  // "<origin>:<line of at>: <key>: <problem>".
  [[noreturn]] void Fail(const YAML::Node& at, const std::string& key,
                         const std::string& problem) const;
  // "<origin>:<line of at>: <text>" (messages of another shape, "<key> = <value>: <rule>").
  [[noreturn]] void FailText(const YAML::Node& at, const std::string& text) const;

  // parent[key]; missing: "<key path>: missing" at the parent's line.
  YAML::Node Required(const YAML::Node& parent, const std::string& key,
                      const std::string& path) const;
  // The mapping parent[key] with only `allowed` keys ("must be a mapping", "<path>.<k>: unknown
  // key"); missing: a null node when `optional`, else "missing".
  YAML::Node Map(const YAML::Node& parent, const std::string& key, const std::string& path,
                 const std::set<std::string>& allowed, bool optional = false) const;
  void CheckKeys(const YAML::Node& map, const std::string& path,
                 const std::set<std::string>& allowed) const;
  // The text of a mapping key (`kv.first`); a key that is a sequence, a mapping or null
  // ("[a, b]: 1", "{a: 1}: 2", "? : 1") fails "<path>: a key must be a plain name".
  std::string KeyAt(const YAML::Node& key, const std::string& path) const;

  // Typed scalars at a node. Messages: "must be a number, got '<text>'", "<path> = <text>: must
  // be a finite number", "<path> = <v>: must be in [lo, hi]", "must be an integer, got '<text>'",
  // "must be true or false, got '<text>'", "must be a string" / "must be a non-empty string".
  double NumberAt(const YAML::Node& n, const std::string& path, const NumberRule& rule = {}) const;
  int IntAt(const YAML::Node& n, const std::string& path, int lo = std::numeric_limits<int>::min(),
            int hi = std::numeric_limits<int>::max()) const;
  bool BoolAt(const YAML::Node& n, const std::string& path) const;
  std::string StringAt(const YAML::Node& n, const std::string& path, bool non_empty = false) const;

  // parent[key] read as above; a missing key gives `def`, or fails "missing" without one. A null
  // `parent` (an optional section left out) reads as missing.
  double Number(const YAML::Node& parent, const std::string& key, const std::string& path,
                std::optional<double> def = std::nullopt, const NumberRule& rule = {}) const;
  int Int(const YAML::Node& parent, const std::string& key, const std::string& path,
          std::optional<int> def = std::nullopt, int lo = std::numeric_limits<int>::min(),
          int hi = std::numeric_limits<int>::max()) const;
  bool Bool(const YAML::Node& parent, const std::string& key, const std::string& path,
            std::optional<bool> def = std::nullopt) const;
  std::string String(const YAML::Node& parent, const std::string& key, const std::string& path,
                     std::optional<std::string> def = std::nullopt, bool non_empty = false) const;

 private:
  YAML::Node Child(const YAML::Node& parent, const std::string& key) const;
  [[noreturn]] void Throw(const std::string& message) const;

  std::string origin_;
  Raise raise_;
};

// Whether a node is a scalar that reads as a number / as true or false (schema checks).
bool IsYamlNumber(const YAML::Node& n);
bool IsYamlBool(const YAML::Node& n);

}  // namespace msmcal::common
