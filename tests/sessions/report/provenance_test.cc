#include "sessions/report/provenance.h"

#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>

#include "sessions/report/build_info.h"
#include "sessions/report/sha256.h"
#include "tests/testing/test_files.h"

namespace msmcal::report {
namespace {

namespace fs = std::filesystem;

TEST(Sha256, KnownVectors) {
  // FIPS 180-4 examples and the padding boundaries (55, 56, 64 bytes).
  EXPECT_EQ(Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(Sha256Hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  EXPECT_EQ(Sha256Hex(std::string(55, 'a')),
            "9f4390f8d30c2dd92ec9f095b65e2b9ae9b0a925a5258e241c9f1e910f734318");
  EXPECT_EQ(Sha256Hex(std::string(56, 'a')),
            "b35439a4ac6f0948b6d6f9e3c6af0f5f590ce20f1bde7090ef7970686ec6738a");
  EXPECT_EQ(Sha256Hex(std::string(64, 'a')),
            "ffe054fe7ae0cb6dc65c3af9b61d5209f439851db43d0ba5997337df154668eb");
}

TEST(Provenance, BuildInfoIsCaptured) {
  EXPECT_STRNE(MsmcalVersion(), "");
  EXPECT_STRNE(BuildType(), "");
  // A git checkout gives a hex commit (maybe "-dirty"), else "unknown"; never empty.
  const std::string c = GitCommit();
  ASSERT_FALSE(c.empty());
  EXPECT_TRUE(c == "unknown" || std::regex_search(c, std::regex("[0-9a-f]{7,}"))) << c;
}

TEST(Provenance, CollectsThisProcessAndHashesTheFolderConfiguration) {
  testing::TempDir tmp;
  testing::Spit(tmp.path() / "session.yaml", "abc");
  const Provenance p = CollectProvenance(tmp.path());
  EXPECT_EQ(p.git_commit, GitCommit());
  EXPECT_NE(p.command_line.find("report_test"), std::string::npos) << p.command_line;
  EXPECT_FALSE(p.host.empty());
  ASSERT_EQ(p.config_sha256.size(), 1u);
  EXPECT_EQ(p.config_sha256[0].first, "session.yaml");
  EXPECT_EQ(p.config_sha256[0].second, Sha256Hex("abc"));
  EXPECT_TRUE(p.instruments.empty());  // no journal
  EXPECT_EQ(IsoUtc(1796167304437242740LL), "2026-12-01T23:21:44Z");
}

TEST(Provenance, RoundTripsThroughSummaryJsonKeepingOtherKeys) {
  testing::TempDir tmp;
  const fs::path f = tmp.path() / "summary.json";
  testing::Spit(f, "{\"mirror_poses\": {\"beams\": 3}}");
  Provenance p;
  p.msmcal_version = "0.1.0";
  p.git_commit = "abc123";
  p.command_line = "msmcal demo --out 'a b'";
  p.instruments = {{"camera", "vendor model serial"}, {"hall_mcu", "fw 1.0 sensor MLX90393"}};
  p.config_sha256 = {{"session.yaml", Sha256Hex("x")}};
  WriteProvenance(f, p);
  const auto back = ReadProvenance(f);
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->command_line, p.command_line);
  EXPECT_EQ(back->instruments, p.instruments);
  EXPECT_EQ(back->config_sha256, p.config_sha256);
  const auto all = nlohmann::json::parse(testing::Slurp(f));
  EXPECT_EQ(all["mirror_poses"]["beams"], 3);
  // The same provenance again: the file is not rewritten.
  const auto mtime = fs::last_write_time(f);
  fs::last_write_time(f, mtime - std::chrono::hours(1));
  WriteProvenance(f, p);
  EXPECT_EQ(fs::last_write_time(f), mtime - std::chrono::hours(1));
}

TEST(Provenance, MalformedKeyNamesTheFileAndField) {
  testing::TempDir tmp;
  const fs::path f = tmp.path() / "summary.json";
  testing::Spit(f, "{\"provenance\": {\"git_commit\": 5}}");
  try {
    (void)ReadProvenance(f);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("summary.json: provenance.git_commit"), std::string::npos)
        << e.what();
  }
}

TEST(Provenance, ResolveKeepsTheSessionsAndAddsWhoRegenerated) {
  testing::TempDir tmp;
  fs::create_directories(tmp.path() / "results");
  Provenance session;
  session.command_line = "msmcal demo --out x";
  session.git_commit = "feedbeef";
  WriteProvenance(tmp.path() / "results" / "summary.json", session);
  const Provenance later = ResolveProvenance(tmp.path(), /*session_process=*/false);
  EXPECT_EQ(later.command_line, "msmcal demo --out x");
  EXPECT_EQ(later.git_commit, "feedbeef");
  EXPECT_NE(later.report_command_line.find("report_test"), std::string::npos);
  EXPECT_EQ(later.report_git_commit, GitCommit());
  // Written back.
  EXPECT_EQ(ReadProvenance(tmp.path() / "results" / "summary.json")->report_git_commit,
            GitCommit());
}

TEST(Provenance, ResolveWithoutStoredProvenanceSaysTheCommandIsUnknown) {
  testing::TempDir tmp;
  fs::create_directories(tmp.path() / "results");
  const Provenance p = ResolveProvenance(tmp.path(), /*session_process=*/false);
  EXPECT_NE(p.command_line.find("unknown"), std::string::npos);
  EXPECT_NE(p.report_command_line.find("report_test"), std::string::npos);
  const Provenance s =
      ResolveProvenance(fs::path(tmp.path()) / "nothing", /*session_process=*/true);
  EXPECT_EQ(s.git_commit, GitCommit());
}

}  // namespace
}  // namespace msmcal::report
