#include "sessions/sweep/sweep_state.h"

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "sessions/interchange/interchange_io.h"

namespace msmcal::sweep {

const char* ToString(PointAction action) {
  switch (action) {
    case PointAction::kAcquire:
      return "acquire";
    case PointAction::kResume:
      return "resume";
    case PointAction::kFinish:
      return "finish";
    case PointAction::kSkip:
      return "skip";
    case PointAction::kSetAside:
      return "set aside";
  }
  return "?";
}

PointAction DecidePointAction(const PointFolderState& s) {
  if (!s.folder_exists || s.folder_empty) return PointAction::kAcquire;
  if (!s.journal_exists) return PointAction::kSetAside;
  if (!s.session_complete) return PointAction::kResume;
  if (!s.results_complete) return PointAction::kFinish;
  return PointAction::kSkip;
}

const char* ToString(PointStatus status) {
  switch (status) {
    case PointStatus::kPending:
      return "pending";
    case PointStatus::kRunning:
      return "running";
    case PointStatus::kDone:
      return "done";
    case PointStatus::kFailed:
      return "failed";
  }
  return "?";
}

namespace {

PointStatus ParseStatus(const std::string& s, const std::string& where) {
  for (PointStatus p :
       {PointStatus::kPending, PointStatus::kRunning, PointStatus::kDone, PointStatus::kFailed})
    if (s == ToString(p)) return p;
  throw std::runtime_error(where + ": unknown status '" + s +
                           "' (expected pending, running, done or failed)");
}

}  // namespace

SweepState ReadSweepState(const std::filesystem::path& file) {
  SweepState state;
  if (!std::filesystem::exists(file)) return state;
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot open the sweep state");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    throw std::runtime_error(file.string() + ": not valid JSON: " + e.what());
  }
  if (!j.is_object() || !j.contains("points") || !j["points"].is_object())
    throw std::runtime_error(file.string() + ": field 'points': expected an object");
  for (const auto& [name, r] : j["points"].items()) {
    const std::string where = file.string() + ": field 'points." + name;
    try {
      PointRecord rec;
      rec.status = ParseStatus(r.at("status").get<std::string>(), where + ".status'");
      rec.reason = r.value("reason", std::string());
      rec.duration_s = r.value("duration_s", 0.0);
      rec.attempts = r.value("attempts", 0);
      rec.skipped_last_run = r.value("skipped_last_run", false);
      state.points[name] = rec;
    } catch (const nlohmann::json::exception& e) {
      throw std::runtime_error(where + "': " + e.what());
    }
  }
  return state;
}

void WriteSweepState(const std::filesystem::path& file, const SweepState& state) {
  nlohmann::json j;
  j["format"] = "msmcal-sweep-state/1";
  j["points"] = nlohmann::json::object();
  for (const auto& [name, r] : state.points) {
    j["points"][name] = {{"status", ToString(r.status)},
                         {"reason", r.reason},
                         {"duration_s", r.duration_s},
                         {"attempts", r.attempts},
                         {"skipped_last_run", r.skipped_last_run}};
  }
  interchange::WriteFileAtomically(file, j.dump(2) + "\n");
}

}  // namespace msmcal::sweep
