#include "sessions/store/catalogue.h"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <ctime>
#include <nlohmann/json.hpp>
#include <tuple>

namespace msmcal::store {
namespace {

namespace fs = std::filesystem;

double ToDouble(const std::optional<std::string>& s) {
  if (!s) return 0;
  double v = 0;
  std::from_chars(s->data(), s->data() + s->size(), v);
  return v;
}

// The headline RMS: the first preferred key present at the top level, else the first number
// (depth first) under a key containing "rms" that is not a baseline's.
std::optional<double> FindRms(const nlohmann::json& j) {
  if (!j.is_object()) return std::nullopt;
  for (const char* key : {"rms", "validation_rms_px", "rms_px", "validation_rms_deg"}) {
    if (j.contains(key) && j[key].is_number()) return j[key].get<double>();
  }
  for (const auto& [key, value] : j.items()) {
    if (key.find("rms") != std::string::npos && key.find("baseline") == std::string::npos &&
        value.is_number()) {
      return value.get<double>();
    }
  }
  for (const auto& [key, value] : j.items()) {
    if (auto v = FindRms(value)) return v;
  }
  return std::nullopt;
}

}  // namespace

std::optional<double> ResultRms(const SessionStore& store) {
  if (const auto v = store.GetMeta("result_rms")) return ToDouble(v);
  const auto summary = store.GetResult("summary.json");
  if (!summary) return std::nullopt;
  try {
    return FindRms(nlohmann::json::parse(*summary));
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::string FormatUtc(int64_t ns) {
  const std::time_t s = static_cast<std::time_t>(ns / 1000000000 - (ns % 1000000000 < 0 ? 1 : 0));
  std::tm tm{};
  gmtime_r(&s, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::optional<int64_t> ParseUtc(const std::string& text) {
  std::tm tm{};
  int n = 0;
  if (std::sscanf(text.c_str(), "%4d-%2d-%2d%n", &tm.tm_year, &tm.tm_mon, &tm.tm_mday, &n) != 3 ||
      n != 10) {
    return std::nullopt;
  }
  if (text.size() > 10) {
    int m = 0;
    if (std::sscanf(text.c_str() + 10, "T%2d:%2d:%2d%n", &tm.tm_hour, &tm.tm_min, &tm.tm_sec, &m) !=
        3) {
      return std::nullopt;
    }
    const std::string rest = text.substr(10 + m);
    if (!rest.empty() && rest != "Z") return std::nullopt;
  }
  if (tm.tm_mon < 1 || tm.tm_mon > 12 || tm.tm_mday < 1 || tm.tm_mday > 31 || tm.tm_hour > 23 ||
      tm.tm_min > 59 || tm.tm_sec > 60) {
    return std::nullopt;
  }
  tm.tm_year -= 1900;
  tm.tm_mon -= 1;
  return static_cast<int64_t>(timegm(&tm)) * 1000000000;
}

std::vector<CatalogueEntry> ListSessions(const fs::path& root, const CatalogueFilter& filter,
                                         const Clock& clock) {
  std::vector<CatalogueEntry> out;
  std::error_code ec;
  if (!fs::is_directory(root, ec)) return out;
  const bool no_conditions = !filter.rig_id && !filter.mirror_id && !filter.since_ns;
  for (const auto& e : fs::directory_iterator(root, ec)) {
    const std::string name = e.path().filename().string();
    if (!e.is_directory() || name.empty() || name[0] == '.') continue;
    if (!fs::exists(e.path() / kSessionDbName)) continue;
    CatalogueEntry entry;
    entry.id = name;
    entry.dir = e.path();
    try {
      const auto store = SessionStore::Open(e.path(), clock, /*read_only=*/true);
      const auto meta = store->AllMeta();
      auto get = [&](const char* key) -> std::optional<std::string> {
        const auto it = meta.find(key);
        if (it == meta.end()) return std::nullopt;
        return it->second;
      };
      if (const auto v = get("created_ns")) {
        std::from_chars(v->data(), v->data() + v->size(), entry.created_ns);
      }
      entry.rig_id = get("rig_id").value_or("");
      entry.mirror_id = get("mirror_id").value_or("");
      entry.fast_frequency_hz = ToDouble(get("drive.fast.frequency_hz"));
      entry.fast_amplitude_vpp = ToDouble(get("drive.fast.amplitude_vpp"));
      entry.slow_frequency_hz = ToDouble(get("drive.slow.frequency_hz"));
      entry.slow_amplitude_vpp = ToDouble(get("drive.slow.amplitude_vpp"));
      entry.frames = store->Counts().frames;
      entry.result_rms = ResultRms(*store);
    } catch (const std::exception& ex) {
      entry.error = ex.what();
    }
    if (!entry.error.empty()) {
      if (no_conditions) out.push_back(entry);
      continue;
    }
    if (filter.rig_id && entry.rig_id != *filter.rig_id) continue;
    if (filter.mirror_id && entry.mirror_id != *filter.mirror_id) continue;
    if (filter.since_ns && entry.created_ns < *filter.since_ns) continue;
    out.push_back(entry);
  }
  std::sort(out.begin(), out.end(), [](const CatalogueEntry& a, const CatalogueEntry& b) {
    return std::tie(a.created_ns, a.id) < std::tie(b.created_ns, b.id);
  });
  return out;
}

fs::path ResolveSession(const std::string& arg, const fs::path& root) {
  std::error_code ec;
  if (fs::is_regular_file(fs::path(arg) / kSessionDbName, ec)) return arg;
  if (fs::is_regular_file(root / arg / kSessionDbName, ec)) return root / arg;
  throw StoreError("no session at '" + arg + "' nor '" + (root / arg).string() +
                   "' (a session folder holds " + kSessionDbName + ")");
}

}  // namespace msmcal::store
