#include "sessions/sweep/sweep_runner.h"

#include <limits>
#include <mutex>
#include <stdexcept>

#include "drivers/generator/safe_state.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::sweep {
namespace {

namespace fs = std::filesystem;

constexpr const char* kPlanFile = "sweep.yaml";
constexpr const char* kStateFile = "sweep_state.json";
constexpr const char* kSummaryFile = "summary.csv";

// A failure's message on one line (the summary's reason, the progress line): its lines joined,
// each list item's "  - " dropped, "; " between them (a space after a line ending in ':'), so a
// multi-line message such as the rig check's list of problems still names its cause.
std::string OneLine(const std::string& s) {
  std::string out;
  size_t begin = 0;
  while (begin <= s.size()) {
    size_t end = s.find('\n', begin);
    if (end == std::string::npos) end = s.size();
    std::string line = s.substr(begin, end - begin);
    const size_t text = line.find_first_not_of(" \t");
    line = text == std::string::npos ? std::string() : line.substr(text);
    if (line.rfind("- ", 0) == 0) line.erase(0, 2);
    if (!line.empty()) out += (out.empty() ? "" : out.back() == ':' ? " " : "; ") + line;
    begin = end + 1;
  }
  return out;
}

// Checks or creates the sweep folder and its plan copy.
void PrepareFolder(const SweepPlan& plan, const fs::path& dir) {
  const fs::path plan_file = dir / kPlanFile;
  if (fs::exists(plan_file)) {
    const SweepPlan stored = LoadSweepPlan(plan_file, plan.parameters);
    if (const std::string diff = ComparePlans(stored, plan); !diff.empty())
      throw std::runtime_error(dir.string() + ": holds a different sweep (" + diff +
                               "); choose another --out, or continue it with `msmcal sweep "
                               "--resume " +
                               dir.string() + "`");
    return;
  }
  if (fs::exists(dir) && !fs::is_directory(dir))
    throw std::runtime_error(dir.string() + ": exists and is not a folder");
  if (fs::exists(dir) && !fs::is_empty(dir))
    throw std::runtime_error(dir.string() + ": exists, is not empty and holds no " + kPlanFile +
                             " (not a sweep folder; choose another --out)");
  fs::create_directories(dir);
  interchange::WriteFileAtomically(plan_file, SweepPlanToYaml(plan));
}

}  // namespace

fs::path SetAsideName(const fs::path& folder) {
  for (int n = 1;; ++n) {
    fs::path p = folder;
    p += ".set-aside-" + std::to_string(n);
    if (!fs::exists(p)) return p;
  }
}

SweepOutcome RunSweep(const SweepPlan& plan, const fs::path& dir, const SweepHooks& hooks) {
  if (!hooks.inspect || !hooks.acquire || !hooks.finish || !hooks.now_s || !hooks.print)
    throw std::invalid_argument("RunSweep: every hook must be set");
  PrepareFolder(plan, dir);
  const std::vector<SweepPoint> points = ExpandPoints(plan);
  const fs::path state_file = dir / kStateFile;
  SweepState state = ReadSweepState(state_file);
  const double t0 = hooks.now_s();

  EtaEstimator eta;
  for (const auto& p : points) {
    auto it = state.points.find(p.name);
    if (it != state.points.end() && it->second.status == PointStatus::kDone &&
        it->second.attempts == 1 && !it->second.skipped_last_run)
      eta.AddPointDuration(it->second.duration_s);
  }
  // Points that still need work, for the ETA (re-evaluated as points finish).
  std::vector<bool> pending(points.size(), true);
  for (size_t i = 0; i < points.size(); ++i)
    pending[i] = DecidePointAction(hooks.inspect(dir / points[i].name)) != PointAction::kSkip;
  auto pending_after = [&](size_t i) {
    size_t n = 0;
    for (size_t k = i + 1; k < points.size(); ++k) n += pending[k] ? 1 : 0;
    return n;
  };

  for (size_t i = 0; i < points.size(); ++i) {
    const SweepPoint& point = points[i];
    const fs::path folder = dir / point.name;
    PointRecord& rec = state.points[point.name];
    const PointAction action = DecidePointAction(hooks.inspect(folder));

    std::mutex mu;
    ProgressSnapshot snap;
    snap.point = i + 1;
    snap.points = points.size();
    snap.label = point.Label();
    const double point_t0 = hooks.now_s();
    bool point_over = false;  // then nothing is left of this point in the ETA
    auto refresh_times = [&] {
      const double now = hooks.now_s();
      snap.elapsed_s = now - t0;
      snap.eta_s = eta.EtaSeconds(
          pending_after(i), point_over ? std::numeric_limits<double>::infinity() : now - point_t0);
    };

    if (action == PointAction::kSkip) {
      rec.status = PointStatus::kDone;
      rec.skipped_last_run = true;
      rec.reason.clear();
      WriteSweepState(state_file, state);
      point_over = true;
      snap.step = "skipped";
      snap.event = "(results complete)";
      const PointFigures f = ReadPointFigures(folder);
      snap.frames_accepted = f.frames_accepted;
      snap.frames_rejected = f.frames_rejected;
      snap.lost = f.hall_lost.value_or(0);
      refresh_times();
      hooks.print(FormatProgressLine(snap), false);
      continue;
    }

    snap.step = "start";
    snap.event = std::string(ToString(action)) + " -> " + folder.string();
    if (action == PointAction::kSetAside) {
      const fs::path aside = SetAsideName(folder);
      fs::rename(folder, aside);
      snap.event = "folder without a journal moved to " + aside.filename().string() +
                   "; acquire -> " + folder.string();
    }
    if (action == PointAction::kFinish) {  // no frame events follow: show what was recorded
      const PointFigures f = ReadPointFigures(folder);
      snap.frames_accepted = f.frames_accepted;
      snap.frames_rejected = f.frames_rejected;
      snap.lost = f.hall_lost.value_or(0);
    }
    refresh_times();
    hooks.print(FormatProgressLine(snap), false);
    rec.status = PointStatus::kRunning;
    rec.skipped_last_run = false;
    rec.reason.clear();
    ++rec.attempts;
    WriteSweepState(state_file, state);

    std::string failure;
    try {
      if (action != PointAction::kFinish) {
        hooks.acquire(point, folder, action == PointAction::kResume,
                      [&](const orchestrator::SessionEvent& e) {
                        std::lock_guard<std::mutex> lock(mu);
                        if (!ApplyEvent(e, &snap)) return;
                        refresh_times();
                        hooks.print(FormatProgressLine(snap), true);
                      });
      }
      {
        std::lock_guard<std::mutex> lock(mu);
        snap.step = "solve + Hall calibration";
        snap.event.clear();
        refresh_times();
        hooks.print(FormatProgressLine(snap), true);
      }
      failure = hooks.finish(point, folder);
    } catch (const gen::SafeStateNotConfirmed& e) {
      // The outputs may be on: no further point runs. The point is recorded as failed (a
      // resume redoes it) and the error goes to the command, which exits with its status.
      rec.duration_s += hooks.now_s() - point_t0;
      rec.status = PointStatus::kFailed;
      rec.reason = OneLine(e.what());
      WriteSweepState(state_file, state);
      throw;
    } catch (const std::exception& e) {
      failure = OneLine(e.what());
      if (failure.empty()) failure = "failed (no message)";
    } catch (...) {
      failure = "failed (unknown exception)";
    }

    const double duration = hooks.now_s() - point_t0;
    rec.duration_s += duration;
    rec.status = failure.empty() ? PointStatus::kDone : PointStatus::kFailed;
    rec.reason = failure;
    WriteSweepState(state_file, state);
    if (failure.empty() && action == PointAction::kAcquire) eta.AddPointDuration(duration);
    pending[i] = false;
    {
      std::lock_guard<std::mutex> lock(mu);
      point_over = true;
      snap.step = failure.empty() ? "done" : "FAILED";
      snap.event = failure.empty() ? "in " + FormatDuration(duration) : failure;
      refresh_times();
      hooks.print(FormatProgressLine(snap), false);
    }
  }

  SweepOutcome outcome;
  for (const auto& p : points) {
    SummaryRow row{p, state.points[p.name], ReadPointFigures(dir / p.name)};
    if (hooks.augment && fs::exists(dir / p.name)) hooks.augment(dir / p.name, &row.figures);
    if (row.record.status == PointStatus::kDone) ++outcome.done;
    if (row.record.status == PointStatus::kFailed) ++outcome.failed;
    outcome.rows.push_back(std::move(row));
  }
  interchange::WriteFileAtomically(dir / kSummaryFile, SummaryCsv(plan, outcome.rows));
  outcome.table = SummaryTable(plan, outcome.rows);
  return outcome;
}

}  // namespace msmcal::sweep
