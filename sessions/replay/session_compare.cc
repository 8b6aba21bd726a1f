#include "sessions/replay/session_compare.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <sstream>
#include <stdexcept>

namespace msmcal::replay {

namespace fs = std::filesystem;

const char* ToString(Verdict verdict) {
  switch (verdict) {
    case Verdict::kSame:
      return "same";
    case Verdict::kDiffers:
      return "DIFFERS";
    case Verdict::kMissingInOriginal:
      return "missing in original";
    case Verdict::kMissingInReplay:
      return "missing in replay";
  }
  return "?";
}

namespace {

// The group names in table order.
const char* const kGroups[] = {"transcript", "session", "images", "hall", "results"};

bool ReadAll(const fs::path& file, std::string* out) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return false;
  std::ostringstream s;
  s << in.rdbuf();
  *out = s.str();
  return true;
}

// Where two texts first differ, as "line N: <a> vs <b>" (lines shortened), or a size note.
std::string FirstDifference(const std::string& a, const std::string& b) {
  const size_t n = std::min(a.size(), b.size());
  size_t i = 0;
  while (i < n && a[i] == b[i]) ++i;
  const size_t line = static_cast<size_t>(std::count(a.begin(), a.begin() + i, '\n')) + 1;
  auto line_at = [i](const std::string& s) {
    const size_t start = s.rfind('\n', i == 0 ? 0 : i - 1);
    const size_t from = (start == std::string::npos || i == 0) ? 0 : start + 1;
    std::string l = s.substr(from, s.find('\n', from) - from);
    if (l.size() > 60) l = l.substr(0, 57) + "...";
    return l;
  };
  if (i == n)
    return "byte " + std::to_string(i) + " (line " + std::to_string(line) + "): one file ends (" +
           std::to_string(a.size()) + " vs " + std::to_string(b.size()) + " bytes)";
  return "line " + std::to_string(line) + ": '" + line_at(a) + "' vs '" + line_at(b) + "'";
}

void CompareBytes(const fs::path& a, const fs::path& b, FileComparison* c) {
  std::string ta, tb;
  if (!ReadAll(a, &ta) || !ReadAll(b, &tb)) {
    c->verdict = Verdict::kDiffers;
    c->detail = "cannot read";
    return;
  }
  if (ta != tb) {
    c->verdict = Verdict::kDiffers;
    c->detail = FirstDifference(ta, tb);
  }
}

void ComparePixels(const fs::path& a, const fs::path& b, FileComparison* c) {
  const cv::Mat ia = cv::imread(a.string(), cv::IMREAD_UNCHANGED);
  const cv::Mat ib = cv::imread(b.string(), cv::IMREAD_UNCHANGED);
  if (ia.empty() || ib.empty()) {
    c->verdict = Verdict::kDiffers;
    c->detail =
        std::string("cannot decode the ") + (ia.empty() ? "original" : "replayed") + " image";
    return;
  }
  if (ia.size() != ib.size() || ia.type() != ib.type()) {
    c->verdict = Verdict::kDiffers;
    c->detail = std::to_string(ia.cols) + "x" + std::to_string(ia.rows) + " type " +
                std::to_string(ia.type()) + " vs " + std::to_string(ib.cols) + "x" +
                std::to_string(ib.rows) + " type " + std::to_string(ib.type());
    return;
  }
  cv::Mat diff;
  cv::compare(ia.reshape(1), ib.reshape(1), diff, cv::CMP_NE);
  const int n = cv::countNonZero(diff);
  if (n > 0) {
    c->verdict = Verdict::kDiffers;
    c->detail = std::to_string(n) + " pixel values differ";
  }
}

void StripTiming(nlohmann::json& j) {
  if (j.is_object()) {
    for (const char* key : kSummaryTimingKeys) j.erase(key);
    for (auto& [k, v] : j.items()) StripTiming(v);
  } else if (j.is_array()) {
    for (auto& v : j) StripTiming(v);
  }
}

nlohmann::json ParseSummary(const std::string& text, const std::string& origin) {
  try {
    nlohmann::json j = nlohmann::json::parse(text);
    if (j.is_object())
      for (const char* key : kSummaryRunKeys) j.erase(key);
    StripTiming(j);
    return j;
  } catch (const nlohmann::json::parse_error& e) {
    throw std::runtime_error(origin + ": not JSON: " + e.what());
  }
}

void CompareSummary(const fs::path& a, const fs::path& b, FileComparison* c) {
  std::string ta, tb;
  if (!ReadAll(a, &ta) || !ReadAll(b, &tb)) {
    c->verdict = Verdict::kDiffers;
    c->detail = "cannot read";
    return;
  }
  try {
    const nlohmann::json ja = ParseSummary(ta, a.string());
    const nlohmann::json jb = ParseSummary(tb, b.string());
    if (ja != jb) {
      c->verdict = Verdict::kDiffers;
      const nlohmann::json patch = nlohmann::json::diff(ja, jb);
      c->detail = "at " + patch.at(0).value("path", std::string("?")) + " (" +
                  std::to_string(patch.size()) + " JSON difference(s), timing keys ignored)";
    }
  } catch (const std::exception& e) {
    c->verdict = Verdict::kDiffers;
    c->detail = e.what();
  }
}

// Regular files under root/sub (recursive), as '/'-separated paths relative to root, filtered.
template <typename Pred>
std::set<std::string> ListFiles(const fs::path& root, const std::string& sub, Pred keep) {
  std::set<std::string> out;
  const fs::path dir = root / sub;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return out;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::end(it);
       it.increment(ec)) {
    if (!it->is_regular_file()) continue;
    const std::string rel = fs::relative(it->path(), root).generic_string();
    if (keep(rel)) out.insert(rel);
  }
  return out;
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Temporaries of atomic writes never count.
bool IsTemporary(const std::string& rel) {
  return rel.find(".tmp") != std::string::npos || EndsWith(rel, "~");
}

}  // namespace

bool SessionComparison::identical() const {
  return std::all_of(files.begin(), files.end(),
                     [](const FileComparison& f) { return f.verdict == Verdict::kSame; });
}

std::vector<FileComparison> SessionComparison::Differences() const {
  std::vector<FileComparison> d;
  for (const auto& f : files)
    if (f.verdict != Verdict::kSame) d.push_back(f);
  return d;
}

std::string SessionComparison::Table() const {
  std::ostringstream s;
  char line[160];
  std::snprintf(line, sizeof(line), "%-12s %6s %6s %8s %8s  %s\n", "compared", "files", "same",
                "differ", "missing", "verdict");
  s << line;
  for (const char* g : kGroups) {
    int n = 0, same = 0, differ = 0, missing = 0;
    for (const auto& f : files) {
      if (f.group != g) continue;
      ++n;
      if (f.verdict == Verdict::kSame)
        ++same;
      else if (f.verdict == Verdict::kDiffers)
        ++differ;
      else
        ++missing;
    }
    const std::string group = g;
    std::string verdict = n == 0 ? "nothing to compare" : (same == n ? "identical" : "DIFFERENT");
    if (group == "results" && !original_has_results)
      verdict = "not compared (the original has no results/)";
    std::snprintf(line, sizeof(line), "%-12s %6d %6d %8d %8d  %s\n", g, n, same, differ, missing,
                  verdict.c_str());
    s << line;
  }
  return s.str();
}

std::string SummaryJsonWithoutTiming(const std::string& json_text, const std::string& origin) {
  return ParseSummary(json_text, origin).dump(2);
}

SessionComparison CompareSessions(const fs::path& original, const fs::path& replay) {
  for (const fs::path& d : {original, replay})
    if (!fs::is_directory(d)) throw std::runtime_error(d.string() + ": no such session folder");
  SessionComparison r;
  r.original_has_results = fs::is_directory(original / "results");

  auto add = [&](const std::string& group, const std::set<std::string>& names, auto compare) {
    for (const auto& rel : names) {
      FileComparison c;
      c.group = group;
      c.file = rel;
      const fs::path a = original / rel, b = replay / rel;
      const bool in_a = fs::is_regular_file(a), in_b = fs::is_regular_file(b);
      if (!in_a) {
        c.verdict = Verdict::kMissingInOriginal;
      } else if (!in_b) {
        c.verdict = Verdict::kMissingInReplay;
      } else {
        compare(a, b, &c);
      }
      r.files.push_back(std::move(c));
    }
  };
  auto both = [&](const std::string& sub, auto keep) {
    std::set<std::string> names = ListFiles(original, sub, keep);
    names.merge(ListFiles(replay, sub, keep));
    return names;
  };
  auto png = [](const std::string& rel) { return EndsWith(rel, ".png") && !IsTemporary(rel); };
  // Recordings cut short by an interruption (hall/<name>.partial-<n>.csv, kept by a resume) are
  // not part of the session's data: a replay runs uninterrupted.
  auto csv = [](const std::string& rel) {
    return EndsWith(rel, ".csv") && !IsTemporary(rel) && rel.find(".partial-") == std::string::npos;
  };
  auto any = [](const std::string& rel) { return !IsTemporary(rel); };

  add("transcript", {"generators_transcript.txt"}, CompareBytes);
  add("session", {"session.yaml", "camera.yaml"}, CompareBytes);
  std::set<std::string> images = both("step1", png);
  images.merge(both("step2", png));
  images.merge(both("rejected", png));
  add("images", images, ComparePixels);
  add("hall", both("hall", csv), CompareBytes);
  if (r.original_has_results) {
    add("results", both("results", any),
        [](const fs::path& a, const fs::path& b, FileComparison* c) {
          if (a.filename() == "summary.json")
            CompareSummary(a, b, c);
          else
            CompareBytes(a, b, c);
        });
  }
  return r;
}

}  // namespace msmcal::replay
