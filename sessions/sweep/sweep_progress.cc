#include "sessions/sweep/sweep_progress.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace msmcal::sweep {

std::string FormatDuration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  const long long s = std::llround(seconds);
  char buf[32];
  if (s < 60)
    std::snprintf(buf, sizeof buf, "%lld s", s);
  else if (s < 3600)
    std::snprintf(buf, sizeof buf, "%lld:%02lld", s / 60, s % 60);
  else
    std::snprintf(buf, sizeof buf, "%lld:%02lld:%02lld", s / 3600, (s / 60) % 60, s % 60);
  return buf;
}

void EtaEstimator::AddPointDuration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return;
  sum_s_ += seconds;
  ++samples_;
}

std::optional<double> EtaEstimator::EtaSeconds(size_t points_after_current,
                                               double current_elapsed_s) const {
  if (samples_ == 0) return std::nullopt;
  const double mean = sum_s_ / static_cast<double>(samples_);
  // The current point: at least nothing left; a point running longer than the mean counts 0.
  const double current_left = std::max(0.0, mean - current_elapsed_s);
  return current_left + mean * static_cast<double>(points_after_current);
}

std::string FormatProgressLine(const ProgressSnapshot& s) {
  std::string line = "sweep " + std::to_string(s.point) + "/" + std::to_string(s.points) + " [" +
                     s.label + "] " + s.step;
  if (!s.event.empty()) line += " " + s.event;
  line += " | frames " + std::to_string(s.frames_accepted) + " ok " +
          std::to_string(s.frames_rejected) + " rejected | lost " + std::to_string(s.lost) +
          " | elapsed " + FormatDuration(s.elapsed_s) + " | ETA " +
          (s.eta_s ? FormatDuration(*s.eta_s) : std::string("?"));
  return line;
}

bool ApplyEvent(const orchestrator::SessionEvent& e, ProgressSnapshot* s) {
  using Kind = orchestrator::SessionEvent::Kind;
  switch (e.kind) {
    case Kind::kFrameDecided:
      s->step = "step " + std::to_string(e.step) + " frame " + std::to_string(e.index + 1) + "/" +
                std::to_string(e.count);
      s->event = e.accepted ? "accepted" : "REJECTED";
      if (e.from_journal) s->event += " (kept from before the resume)";
      (e.accepted ? s->frames_accepted : s->frames_rejected) += 1;
      return true;
    case Kind::kHallStarted:
      s->step = "Hall " + e.recording;
      s->event = "recording";
      return true;
    case Kind::kHallDone:
      s->step = "Hall " + e.recording;
      s->event = std::to_string(e.readings) + " readings";
      s->lost += e.lost;
      return true;
    case Kind::kSessionWritten:
      s->step = "session written";
      s->event.clear();
      return true;
    case Kind::kStepState:
    case Kind::kSafeState:
      break;
  }
  return false;
}

}  // namespace msmcal::sweep
