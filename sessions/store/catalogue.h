#pragma once
// The catalogue across sessions: a root folder (default ./sessions) whose subfolders are
// sessions (each with a session.db). Lists the figures a lab filters by.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "sessions/store/session_store.h"

namespace msmcal::store {

struct CatalogueEntry {
  std::string id;  // the subfolder's name
  std::filesystem::path dir;
  int64_t created_ns = 0;
  std::string rig_id;
  std::string mirror_id;
  double fast_frequency_hz = 0, fast_amplitude_vpp = 0;
  double slow_frequency_hz = 0, slow_amplitude_vpp = 0;
  int64_t frames = 0;
  std::optional<double> result_rms;
  std::string error;  // non-empty: the folder could not be read (the other fields are unset)
};

struct CatalogueFilter {
  std::optional<std::string> rig_id;     // exact match
  std::optional<std::string> mirror_id;  // exact match
  std::optional<int64_t> since_ns;       // created at or after
};

// Sessions under `root`, oldest first; folders that fail to open are listed with `error` set
// (and pass only a filter without conditions). Hidden folders (staging imports) are skipped.
std::vector<CatalogueEntry> ListSessions(const std::filesystem::path& root,
                                         const CatalogueFilter& filter, const Clock& clock);

// The headline RMS of a session's results: meta key "result_rms" if set, else from
// results/summary.json (as `msmcal solve` writes it) the first of "rms", "validation_rms_px",
// "rms_px", "validation_rms_deg" at the top level, else the first number (depth first) under a
// key containing "rms" and not "baseline".
std::optional<double> ResultRms(const SessionStore& store);

// "2026-11-23T11:40:05Z" (UTC, seconds).
std::string FormatUtc(int64_t ns);
// Parses "YYYY-MM-DD" or "YYYY-MM-DDTHH:MM:SS[Z]" (UTC) to ns since the epoch.
std::optional<int64_t> ParseUtc(const std::string& text);

// A session folder from a command-line argument: `arg` itself if it holds a session.db, else
// root/arg. Throws StoreError naming both if neither does.
std::filesystem::path ResolveSession(const std::string& arg, const std::filesystem::path& root);

}  // namespace msmcal::store
