#include "common/yaml_fields.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace msmcal::common {
namespace {

using ::testing::HasSubstr;

// The message of what `f` throws (std::runtime_error), or "" when it does not throw.
template <typename F>
std::string Message(F f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

constexpr const char* kDoc =
    "camera:\n"         // 1
    "  fx: 1200.5\n"    // 2
    "  cols: 4096\n"    // 3
    "  name: ''\n"      // 4
    "  fy: .nan\n"      // 5
    "  mono: true\n"    // 6
    "  lens: [1, 2]\n"  // 7
    "  gain: high\n";   // 8

TEST(YamlFieldsTest, RequiredAndOptionalTypedFields) {
  const YamlFields r("rig.yaml");
  const YAML::Node root = r.Load(kDoc);
  const YAML::Node cam =
      r.Map(root, "camera", "camera", {"fx", "cols", "name", "fy", "mono", "lens", "gain"});
  EXPECT_DOUBLE_EQ(r.Number(cam, "fx", "camera.fx"), 1200.5);
  EXPECT_EQ(r.Int(cam, "cols", "camera.cols", std::nullopt, 1, 100000), 4096);
  EXPECT_TRUE(r.Bool(cam, "mono", "camera.mono"));
  EXPECT_EQ(r.String(cam, "name", "camera.name"), "");
  EXPECT_DOUBLE_EQ(r.Number(cam, "k1", "camera.k1", 0.25), 0.25);
  EXPECT_EQ(r.Int(cam, "rows", "camera.rows", 3000), 3000);
  EXPECT_FALSE(r.Bool(cam, "colour", "camera.colour", false));
  EXPECT_EQ(r.String(cam, "serial", "camera.serial", "none"), "none");
  // An optional section left out reads as missing.
  EXPECT_TRUE(r.Map(root, "hall", "hall", {}, /*optional=*/true).IsNull());
  EXPECT_DOUBLE_EQ(r.Number(YAML::Node(), "x", "hall.x", 1.5), 1.5);
}

TEST(YamlFieldsTest, MessagesNameOriginLineKeyAndProblem) {
  const YamlFields r("rig.yaml");
  const YAML::Node root = r.Load(kDoc);
  const YAML::Node cam = root["camera"];
  EXPECT_EQ(Message([&] { r.Number(cam, "k1", "camera.k1"); }), "rig.yaml:2: camera.k1: missing");
  EXPECT_EQ(Message([&] { r.Number(cam, "gain", "camera.gain"); }),
            "rig.yaml:8: camera.gain: must be a number, got 'high'");
  EXPECT_EQ(Message([&] { r.Number(cam, "fy", "camera.fy"); }),
            "rig.yaml:5: camera.fy = .nan: must be a finite number");
  EXPECT_EQ(
      Message([&] { r.Number(cam, "fx", "camera.fx", std::nullopt, NumberRule::In(0, 1000)); }),
      "rig.yaml:2: camera.fx = 1200.5: must be in [0, 1000]");
  EXPECT_EQ(
      Message([&] { r.Number(cam, "cols", "camera.cols", std::nullopt, NumberRule::Above(4096)); }),
      "rig.yaml:3: camera.cols = 4096: must be in (4096, inf]");
  EXPECT_EQ(Message([&] { r.Int(cam, "cols", "camera.cols", std::nullopt, 1, 100); }),
            "rig.yaml:3: camera.cols = 4096: must be in [1, 100]");
  EXPECT_EQ(Message([&] { r.Int(cam, "fx", "camera.fx"); }),
            "rig.yaml:2: camera.fx: must be an integer, got '1200.5'");
  EXPECT_EQ(Message([&] { r.Bool(cam, "gain", "camera.gain"); }),
            "rig.yaml:8: camera.gain: must be true or false, got 'high'");
  EXPECT_EQ(Message([&] { r.String(cam, "lens", "camera.lens"); }),
            "rig.yaml:7: camera.lens: must be a string");
  EXPECT_EQ(Message([&] { r.String(cam, "name", "camera.name", std::nullopt, true); }),
            "rig.yaml:4: camera.name: must be a non-empty string");
  EXPECT_EQ(Message([&] { r.Map(root, "camera", "camera", {"fx"}); }),
            "rig.yaml:3: camera.cols: unknown key");
  EXPECT_EQ(Message([&] { r.Map(cam, "lens", "camera.lens", {}); }),
            "rig.yaml:7: camera.lens: must be a mapping");
  EXPECT_EQ(Message([&] { r.Required(root, "hall", "hall"); }), "rig.yaml:1: hall: missing");
}

TEST(YamlFieldsTest, InfiniteOnlyWhereAllowedAndTheNoteFollows) {
  const YamlFields r("rig.yaml");
  const YAML::Node n = r.Load("load_ohm: .inf\nmax_vpp: -.inf\n");
  EXPECT_TRUE(std::isinf(r.Number(n, "load_ohm", "load_ohm", std::nullopt,
                                  NumberRule::In(0, INFINITY).AllowInfinite())));
  EXPECT_EQ(Message([&] {
              r.Number(n, "max_vpp", "max_vpp", std::nullopt,
                       NumberRule().Note("(inf is accepted only for load_ohm)"));
            }),
            "rig.yaml:2: max_vpp = -.inf: must be a finite number (inf is accepted only for "
            "load_ohm)");
}

TEST(YamlFieldsTest, SyntaxErrorsAndNodesWithoutALine) {
  const YamlFields r("plan.yaml");
  const std::string m = Message([&] { r.Load("a: [1, 2\nb: 3\n", "YAML syntax error: "); });
  EXPECT_THAT(m, HasSubstr("plan.yaml:"));
  EXPECT_THAT(m, HasSubstr(": YAML syntax error: "));
  EXPECT_EQ(YamlLine(YAML::Node()), 0);
  EXPECT_EQ(YamlWhere("plan.yaml", YAML::Node()), "plan.yaml");
  EXPECT_EQ(Message([&] { r.Fail(YAML::Node(), "base", "expected a mapping"); }),
            "plan.yaml: base: expected a mapping");
}

struct CustomError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

TEST(YamlFieldsTest, RaiseThrowsTheCallersException) {
  const YamlFields r("m.yaml", [](const std::string& m) { throw CustomError(m); });
  const YAML::Node n = r.Load("a: x\n");
  EXPECT_THROW(r.Number(n, "a", "a"), CustomError);
  EXPECT_THROW(r.Load("a: [\n"), CustomError);
}

TEST(YamlFieldsTest, SchemaPredicatesAndNumbersInMessages) {
  const YAML::Node n = YAML::Load("{a: 1.5, b: yes, c: x, d: [1]}");
  EXPECT_TRUE(IsYamlNumber(n["a"]));
  EXPECT_FALSE(IsYamlNumber(n["c"]));
  EXPECT_FALSE(IsYamlNumber(n["d"]));
  EXPECT_TRUE(IsYamlBool(n["b"]));
  EXPECT_FALSE(IsYamlBool(n["a"]));
  EXPECT_EQ(FieldNumber(200000), "200000");
  EXPECT_EQ(FieldNumber(0.1), "0.1");
}

// A mapping key that is a sequence, a mapping or null is refused with its line (the rig file
// fuzzer found "[a, b]: 1" escaping as yaml-cpp's "bad conversion").
TEST(YamlFieldsTest, KeysThatAreNotPlainNamesAreRefusedWithTheirLine) {
  const YamlFields r("rig.yaml");
  const YAML::Node root = r.Load("camera:\n  fx: 1\n  [a, b]: 2\n  {c: 1}: 3\n");
  std::vector<std::string> messages;
  for (const auto& kv : root["camera"]) {
    messages.push_back(Message([&] { (void)r.KeyAt(kv.first, "camera"); }));
  }
  ASSERT_EQ(messages.size(), 3u);
  EXPECT_EQ(messages[0], "");
  EXPECT_EQ(messages[1], "rig.yaml:3: camera: a key must be a plain name");
  EXPECT_EQ(messages[2], "rig.yaml:4: camera: a key must be a plain name");
  EXPECT_EQ(Message([&] { r.CheckKeys(root["camera"], "camera", {"fx"}); }),
            "rig.yaml:3: camera: a key must be a plain name");
  EXPECT_EQ(r.KeyAt(root.begin()->first, "(root)"), "camera");
}

}  // namespace
}  // namespace msmcal::common
