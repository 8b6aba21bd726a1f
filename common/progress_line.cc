#include "common/progress_line.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

namespace msmcal::common {
namespace {

std::string Duration(double s) {
  const long t = std::lround(std::max(0.0, s));
  char buf[32];
  if (t >= 3600)
    std::snprintf(buf, sizeof(buf), "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  else
    std::snprintf(buf, sizeof(buf), "%ld:%02ld", t / 60, t % 60);
  return buf;
}

double SteadySeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

std::string FormatProgressLine(const std::string& label, size_t done, size_t total,
                               const std::string& unit, double elapsed_s,
                               const std::string& detail) {
  done = std::min(done, total);
  const int percent = total > 0 ? static_cast<int>(100.0 * done / total) : 100;
  std::string s = label + ": " + std::to_string(done) + "/" + std::to_string(total);
  if (!unit.empty()) s += " " + unit;
  s += " (" + std::to_string(percent) + "%), " + Duration(elapsed_s) + " elapsed, ETA ";
  s += done > 0 ? Duration(elapsed_s / done * (total - done)) : std::string("-");
  if (!detail.empty()) s += "  " + detail;
  return s;
}

ProgressLine::ProgressLine(std::string label, size_t total, std::string unit, std::FILE* stream)
    : ProgressLine(std::move(label), total, std::move(unit), stream,
                   stream != nullptr && ::isatty(::fileno(stream)) == 1, SteadySeconds) {}

ProgressLine::ProgressLine(std::string label, size_t total, std::string unit, std::FILE* stream,
                           bool enabled, std::function<double()> clock_s)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(total),
      stream_(stream),
      enabled_(enabled && stream != nullptr),
      clock_s_(std::move(clock_s)),
      start_s_(clock_s_()) {
  std::lock_guard<std::mutex> lock(mu_);
  DrawLocked(/*force=*/true);
}

ProgressLine::~ProgressLine() { Finish(); }

void ProgressLine::Update(size_t done, const std::string& detail) {
  std::lock_guard<std::mutex> lock(mu_);
  done_ = std::min(std::max(done, done_), total_);
  if (!detail.empty()) detail_ = detail;
  DrawLocked(done_ == total_);
}

void ProgressLine::Step(const std::string& detail) {
  std::lock_guard<std::mutex> lock(mu_);
  done_ = std::min(done_ + 1, total_);
  if (!detail.empty()) detail_ = detail;
  DrawLocked(done_ == total_);
}

void ProgressLine::DrawLocked(bool force) {
  if (!enabled_ || finished_) return;
  const double now = clock_s_();
  if (!force && now - last_draw_s_ < 0.2) return;
  last_draw_s_ = now;
  const std::string line =
      FormatProgressLine(label_, done_, total_, unit_, now - start_s_, detail_);
  std::fprintf(stream_, "\r%s\x1b[K", line.c_str());
  std::fflush(stream_);
  drawn_ = true;
}

void ProgressLine::Finish() {
  std::lock_guard<std::mutex> lock(mu_);
  if (finished_) return;
  if (enabled_ && drawn_) {
    DrawLocked(/*force=*/true);
    std::fputc('\n', stream_);
    std::fflush(stream_);
  }
  finished_ = true;
}

}  // namespace msmcal::common
