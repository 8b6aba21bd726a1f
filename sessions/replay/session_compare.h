#pragma once
// Compares a replayed session folder with the original (issue 9: "a replay reproduces the
// original results exactly"): the generators' SCPI transcript, session.yaml and camera.yaml, every
// image (decoded, pixel for pixel: accepted step1/ step2/ frames and the rejected/ ones), every
// Hall file (hall/*.csv), and every file under results/ byte for byte — except
// results/summary.json, compared as JSON with the solve-time keys (kSummaryTimingKeys, at any
// depth) and the run's provenance (kSummaryRunKeys) removed. Logs, journals (session.db), truth/, report.html and Hall recordings cut short
// by an interruption (hall/*.partial-<n>.csv) are not compared.

#include <filesystem>
#include <string>
#include <vector>

namespace msmcal::replay {

// Keys of results/summary.json that measure time (app/cmd_solve.cc), ignored by the comparison.
inline constexpr const char* kSummaryTimingKeys[] = {"solve_time_s", "ceres_time_s"};
// Top-level keys of results/summary.json that describe the run, not its results (the report's
// provenance: command line, host, times, instruments), ignored by the comparison.
inline constexpr const char* kSummaryRunKeys[] = {"provenance"};

enum class Verdict { kSame, kDiffers, kMissingInOriginal, kMissingInReplay };
const char* ToString(Verdict verdict);  // "same" | "DIFFERS" | "missing in original" | ...

struct FileComparison {
  std::string group;  // "transcript" | "session" | "images" | "hall" | "results"
  std::string file;   // relative to the session folder, '/' separated
  Verdict verdict = Verdict::kSame;
  std::string detail;  // what differs (first differing line, pixel count, JSON path)
};

struct SessionComparison {
  std::vector<FileComparison> files;  // grouped, sorted by file within a group
  bool original_has_results = false;  // false: results/ not compared (acquisition only)
  bool identical() const;             // every file kSame
  std::vector<FileComparison> Differences() const;
  // One row per group: files compared, same, differing, missing (fixed-width text table).
  std::string Table() const;
};

// Both folders must exist (std::runtime_error naming the one that does not). Never throws for
// content: unreadable or undecodable files are reported as differences with the reason.
SessionComparison CompareSessions(const std::filesystem::path& original,
                                  const std::filesystem::path& replay);

// summary.json text re-serialised (sorted keys, 2-space indent) without kSummaryTimingKeys at any
// depth. Throws std::runtime_error naming `origin` when the text is not JSON.
std::string SummaryJsonWithoutTiming(const std::string& json_text, const std::string& origin);

}  // namespace msmcal::replay
