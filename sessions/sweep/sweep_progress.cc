#include "sessions/sweep/sweep_progress.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <regex>
#include <sstream>

namespace msmcal::sweep {
namespace {

std::string StripTimePrefix(const std::string& line) {
  static const std::regex kPrefix(R"(^\[\s*[-0-9.]+ s\]\s*)");
  return std::regex_replace(line, kPrefix, "", std::regex_constants::format_first_only);
}

}  // namespace

LogEvent ParseLogLine(const std::string& raw) {
  static const std::regex kFrame(
      R"(^step ([12]): frame (\d+)/(\d+) (\S+) (accepted|REJECTED|rejected)\b)");
  static const std::regex kHallStart(R"(^Hall: (background|actual) recording on)");
  static const std::regex kHallDone(
      R"(^Hall: (background|actual) (\d+) readings, \d+ clock edges, (\d+) lost)");
  const std::string line = StripTimePrefix(raw);
  LogEvent e;
  std::smatch m;
  if (std::regex_search(line, m, kFrame)) {
    e.kind = LogEvent::Kind::kFrame;
    e.step = std::stoi(m[1]);
    e.index = std::stoul(m[2]);
    e.count = std::stoul(m[3]);
    e.file = m[4];
    e.accepted = m[5] == "accepted";
    e.from_journal = line.find("before the resume") != std::string::npos;
  } else if (std::regex_search(line, m, kHallDone)) {
    e.kind = LogEvent::Kind::kHallDone;
    e.recording = m[1];
    e.readings = std::stoull(m[2]);
    e.lost = std::stoull(m[3]);
  } else if (std::regex_search(line, m, kHallStart)) {
    e.kind = LogEvent::Kind::kHallStart;
    e.recording = m[1];
  } else if (line.rfind("session written", 0) == 0) {
    e.kind = LogEvent::Kind::kSessionWritten;
  }
  return e;
}

SessionLogFigures ParseSessionLog(const std::string& text) {
  std::map<std::string, bool> frames;                         // file -> last decision
  std::map<std::string, std::pair<uint64_t, uint64_t>> hall;  // recording -> (readings, lost)
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    const LogEvent e = ParseLogLine(line);
    if (e.kind == LogEvent::Kind::kFrame) frames[e.file] = e.accepted;
    if (e.kind == LogEvent::Kind::kHallDone) hall[e.recording] = {e.readings, e.lost};
  }
  SessionLogFigures f;
  for (const auto& [file, ok] : frames) (ok ? f.frames_accepted : f.frames_rejected) += 1;
  for (const auto& [name, rl] : hall) {
    f.hall_readings += rl.first;
    f.hall_lost += rl.second;
    f.hall_seen = true;
  }
  return f;
}

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

bool ApplyLogLine(const std::string& line, ProgressSnapshot* s) {
  const LogEvent e = ParseLogLine(line);
  switch (e.kind) {
    case LogEvent::Kind::kFrame:
      s->step = "step " + std::to_string(e.step) + " frame " + std::to_string(e.index) + "/" +
                std::to_string(e.count);
      s->event = e.accepted ? "accepted" : "REJECTED";
      if (e.from_journal) s->event += " (kept from before the resume)";
      (e.accepted ? s->frames_accepted : s->frames_rejected) += 1;
      return true;
    case LogEvent::Kind::kHallStart:
      s->step = "Hall " + e.recording;
      s->event = "recording";
      return true;
    case LogEvent::Kind::kHallDone:
      s->step = "Hall " + e.recording;
      s->event = std::to_string(e.readings) + " readings";
      s->lost += e.lost;
      return true;
    case LogEvent::Kind::kSessionWritten:
      s->step = "session written";
      s->event.clear();
      return true;
    case LogEvent::Kind::kOther:
      break;
  }
  return false;
}

}  // namespace msmcal::sweep
