#include "sessions/report/provenance.h"

#include <unistd.h>

#include <algorithm>
#include <ctime>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "common/text_io.h"
#include "sessions/report/build_info.h"
#include "sessions/report/sha256.h"
#include "sessions/results/results_files.h"
#include "sessions/store/session_store.h"

namespace msmcal::report {
namespace {

namespace fs = std::filesystem;

std::string ShellQuote(const std::string& arg) {
  if (!arg.empty() && arg.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                            "0123456789_-./=:,+@%") == std::string::npos)
    return arg;
  std::string q = "'";
  for (char c : arg) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::vector<std::string> ThisArguments() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::vector<std::string> args;
  std::string a;
  while (std::getline(in, a, '\0')) args.push_back(a);
  return args;
}

void AddHash(const std::string& name, const fs::path& file, Provenance* p) {
  for (const auto& [n, h] : p->config_sha256)
    if (n == name) return;
  try {
    p->config_sha256.emplace_back(name, Sha256HexOfFile(file));
  } catch (const std::exception& e) {
    p->config_sha256.emplace_back(name, std::string("unreadable: ") + e.what());
  }
}

std::string Str(const nlohmann::json& j, const char* key, const std::string& file) {
  if (!j.contains(key)) return "";
  if (!j[key].is_string())
    throw std::runtime_error(file + ": provenance." + key + ": expected a string");
  return j[key].get<std::string>();
}

std::vector<std::pair<std::string, std::string>> Pairs(const nlohmann::json& j, const char* key,
                                                       const std::string& file) {
  std::vector<std::pair<std::string, std::string>> out;
  if (!j.contains(key)) return out;
  if (!j[key].is_array())
    throw std::runtime_error(file + ": provenance." + key + ": expected a list");
  for (const auto& e : j[key]) {
    if (!e.is_array() || e.size() != 2 || !e[0].is_string() || !e[1].is_string())
      throw std::runtime_error(file + ": provenance." + key +
                               ": expected [name, value] string pairs");
    out.emplace_back(e[0].get<std::string>(), e[1].get<std::string>());
  }
  return out;
}

nlohmann::json ReadAll(const fs::path& file) {
  nlohmann::json all = nlohmann::json::object();
  if (!fs::exists(file)) return all;
  std::ifstream in(file);
  try {
    all = nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    throw std::runtime_error(file.string() + ": not JSON: " + e.what());
  }
  if (!all.is_object()) throw std::runtime_error(file.string() + ": not a JSON object");
  return all;
}

}  // namespace

std::string ThisCommandLine() {
  std::string line;
  for (const auto& a : ThisArguments()) line += (line.empty() ? "" : " ") + ShellQuote(a);
  return line;
}

std::string IsoUtc(long long unix_ns) {
  const std::time_t s = static_cast<std::time_t>(unix_ns / 1000000000LL);
  std::tm tm{};
  gmtime_r(&s, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

Provenance CollectProvenance(const fs::path& dir) {
  Provenance p;
  p.msmcal_version = MsmcalVersion();
  p.git_commit = GitCommit();
  p.build_type = BuildType();
  p.command_line = ThisCommandLine();
  char host[256] = {};
  p.host = gethostname(host, sizeof(host) - 1) == 0 ? host : "unknown";
  for (const char* f :
       {"session.yaml", "camera.yaml", "results/solve_options.yaml", "truth/sim_config.yaml"})
    if (fs::is_regular_file(dir / f)) AddHash(f, dir / f, &p);
  const auto args = ThisArguments();
  for (size_t i = 1; i < args.size(); ++i) {
    const fs::path a = args[i];
    std::error_code ec;
    if ((a.extension() == ".yaml" || a.extension() == ".yml") && fs::is_regular_file(a, ec))
      AddHash(args[i], a, &p);
  }
  if (fs::exists(dir / store::kSessionDbName)) {
    try {
      const store::SystemClock clock;
      const auto journal = store::SessionStore::Open(dir, clock, /*read_only=*/true);
      p.instruments = journal->Instruments();
      if (const auto created = journal->GetMeta("created_ns"))
        p.start_utc = IsoUtc(std::stoll(*created));
      const auto events = journal->Events(/*limit=*/1);
      if (!events.empty()) p.end_utc = IsoUtc(events.back().wall_time_ns);
    } catch (const std::exception& e) {
      p.instruments.emplace_back("journal", std::string("unreadable: ") + e.what());
    }
  }
  return p;
}

std::optional<Provenance> ReadProvenance(const fs::path& summary_json) {
  const nlohmann::json all = ReadAll(summary_json);
  if (!all.contains("provenance")) return std::nullopt;
  const nlohmann::json& j = all["provenance"];
  const std::string f = summary_json.string();
  if (!j.is_object()) throw std::runtime_error(f + ": provenance: expected an object");
  Provenance p;
  p.msmcal_version = Str(j, "msmcal_version", f);
  p.git_commit = Str(j, "git_commit", f);
  p.build_type = Str(j, "build_type", f);
  p.command_line = Str(j, "command_line", f);
  p.host = Str(j, "host", f);
  p.start_utc = Str(j, "start_utc", f);
  p.end_utc = Str(j, "end_utc", f);
  p.config_sha256 = Pairs(j, "config_sha256", f);
  p.instruments = Pairs(j, "instruments", f);
  p.report_command_line = Str(j, "report_command_line", f);
  p.report_git_commit = Str(j, "report_git_commit", f);
  p.report_time_utc = Str(j, "report_time_utc", f);
  return p;
}

void WriteProvenance(const fs::path& summary_json, const Provenance& p) {
  nlohmann::json j = {{"msmcal_version", p.msmcal_version},
                      {"git_commit", p.git_commit},
                      {"build_type", p.build_type},
                      {"command_line", p.command_line},
                      {"host", p.host},
                      {"start_utc", p.start_utc},
                      {"end_utc", p.end_utc}};
  auto pairs = [](const std::vector<std::pair<std::string, std::string>>& v) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& [k, x] : v) a.push_back({k, x});
    return a;
  };
  j["config_sha256"] = pairs(p.config_sha256);
  j["instruments"] = pairs(p.instruments);
  if (!p.report_command_line.empty()) {
    j["report_command_line"] = p.report_command_line;
    j["report_git_commit"] = p.report_git_commit;
    j["report_time_utc"] = p.report_time_utc;
  }
  results::UpdateSummaryJson(summary_json, "provenance", std::move(j));
}

Provenance ResolveProvenance(const fs::path& dir, bool session_process) {
  const fs::path summary = dir / "results" / "summary.json";
  std::optional<Provenance> stored;
  try {
    stored = ReadProvenance(summary);
  } catch (const std::exception&) {
    stored.reset();  // malformed: collected again below and rewritten
  }
  Provenance p;
  if (stored) {
    p = *stored;
    if (!session_process) {
      p.report_command_line = ThisCommandLine();
      p.report_git_commit = GitCommit();
      p.report_time_utc = IsoUtc(static_cast<long long>(store::SystemClock().NowNs()));
    }
  } else {
    p = CollectProvenance(dir);
    if (!session_process) {
      p.report_command_line = p.command_line;
      p.report_git_commit = p.git_commit;
      p.report_time_utc = IsoUtc(static_cast<long long>(store::SystemClock().NowNs()));
      p.command_line =
          "unknown (the session recorded no provenance; this report was written later)";
      p.git_commit = "unknown (see report_git_commit)";
      p.msmcal_version = "unknown";
      p.build_type = "unknown";
    }
  }
  if (fs::is_directory(dir / "results")) {
    try {
      WriteProvenance(summary, p);
    } catch (const std::exception&) {
      // The report still shows it; a read-only folder keeps its summary.json.
    }
  }
  return p;
}

}  // namespace msmcal::report
