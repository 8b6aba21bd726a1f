#pragma once
// Provenance of a calibration: what produced it (msmcal version, git commit, build type, the
// command line, host), with which configuration (SHA-256 of the configuration files), on which
// instruments (the identities the rig check recorded in the session journal) and when (the
// journal's first and last times). Kept in results/summary.json under "provenance" and shown in
// the report.
//
// The session's provenance is collected once, by the process that ran the session (demo,
// session run, resume, sweep), when it first writes the report; `msmcal report DIR` later keeps it
// and only adds who regenerated the report (report_*).

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace msmcal::report {

struct Provenance {
  std::string msmcal_version, git_commit, build_type;
  std::string command_line;  // the session's (arguments joined by spaces, shell-quoted if needed)
  std::string host;
  std::string start_utc, end_utc;  // ISO 8601, from the journal ("" when there is none)
  // Configuration files (path relative to the session folder, or as given on the command line)
  // and their SHA-256.
  std::vector<std::pair<std::string, std::string>> config_sha256;
  // Instrument role (generator1, generator2, camera, hall_mcu) -> identity (IDN with firmware,
  // vendor / model / serial, MCU firmware and sensor); from the journal.
  std::vector<std::pair<std::string, std::string>> instruments;
  // The process that (re)wrote the report, when it is not the session's.
  std::string report_command_line, report_git_commit, report_time_utc;
};

// This process's command line (/proc/self/cmdline), shell-quoted; "" when unreadable.
std::string ThisCommandLine();
// UTC time as ISO 8601 ("2026-12-01T23:22:41Z") from nanoseconds since the epoch.
std::string IsoUtc(long long unix_ns);

// The provenance of `dir` as this process sees it: this binary, this command line and host, the
// journal's instruments and times, and the hashes of session.yaml, camera.yaml,
// results/solve_options.yaml, truth/sim_config.yaml and of every existing .yaml file named on the
// command line. Never throws: what cannot be read is left empty and said in the field.
Provenance CollectProvenance(const std::filesystem::path& dir);

// results/summary.json "provenance" (null when absent). Throws std::runtime_error naming the file
// and the field when the key exists but is malformed.
std::optional<Provenance> ReadProvenance(const std::filesystem::path& summary_json);
// Replaces the "provenance" key of `summary_json` (created if absent), keeping the other keys; a
// file whose text would not change is left untouched (same mtime).
void WriteProvenance(const std::filesystem::path& summary_json, const Provenance& provenance);

// The session's provenance for a report of `dir`: results/summary.json's when it has one (with
// report_* set to this process), else CollectProvenance(dir), written back to summary.json when
// results/ exists. `session_process`: this process ran the session (else the command line is
// unknown and said so).
Provenance ResolveProvenance(const std::filesystem::path& dir, bool session_process);

}  // namespace msmcal::report
