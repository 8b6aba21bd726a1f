#include "sessions/orchestrator/console_operator.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <sstream>
#include <utility>

namespace msmcal::orchestrator {
namespace {

std::string JoinInts(const std::vector<int>& v) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) {
    if (i > 0) s += (i + 1 == v.size()) ? " and " : ", ";
    s += std::to_string(v[i]);
  }
  return s;
}

std::string Header(int number, int total, const std::string& title) {
  return "\n=== [" + std::to_string(number) + "/" + std::to_string(total) + "] " + title + " ===\n";
}

// "unblock beams 1, 2 and 3 (all beams)" / "unblock beam 2 only; block beams 1 and 3 ...".
std::string BeamsLine(const dataset::Recording& plan, const std::vector<int>& beams) {
  std::vector<int> blocked;
  for (const auto& b : plan.beams)
    if (std::find(beams.begin(), beams.end(), b.id) == beams.end()) blocked.push_back(b.id);
  if (beams.empty())
    return "Block every beam (background frame: the board without laser dots, for the dot fit).";
  if (blocked.empty())
    return std::string("Unblock ") + (beams.size() == 1 ? "beam " : "beams ") + JoinInts(beams) +
           " (all beams).";
  return std::string("Unblock ") + (beams.size() == 1 ? "beam " : "beams ") + JoinInts(beams) +
         " only; block " + (blocked.size() == 1 ? "beam " : "beams ") + JoinInts(blocked) +
         (beams.size() == 1 ? " (identification frame: tells which dot is which beam)." : ".");
}

std::string Numbered(const std::vector<std::string>& items) {
  std::string s;
  for (size_t i = 0; i < items.size(); ++i)
    s += "  " + std::to_string(i + 1) + ". " + items[i] + "\n";
  return s;
}

int PoseCount(const dataset::Recording& plan) {
  int n = 0;
  for (const auto& f : plan.step1) n = std::max(n, f.pose + 1);
  return n;
}

}  // namespace

std::string ConsoleOperatorOptions::Validate(bool has_inner) const {
  if (input_fd < 0)
    return "ConsoleOperatorOptions.input_fd = " + std::to_string(input_fd) + ": must be >= 0";
  if (output_fd < 0)
    return "ConsoleOperatorOptions.output_fd = " + std::to_string(output_fd) + ": must be >= 0";
  if (settle_ns < 0)
    return "ConsoleOperatorOptions.settle_ns = " + std::to_string(settle_ns) + ": must be >= 0";
  if (!has_inner) {
    if (mcu_device.empty())
      return "ConsoleOperatorOptions.mcu_device = '': required without an inner operator (lab)";
    if (!host_clock_ns)
      return "ConsoleOperatorOptions.host_clock_ns = (none): required without an inner operator "
             "(lab)";
  }
  return {};
}

std::string DescribeHallRecording(const dataset::Recording& plan, HallRun run, bool before_step1,
                                  int number, int total) {
  std::vector<std::string> items;
  if (run == HallRun::kBackground) {
    items.push_back(
        "Remove the mirror's top frame (magnet away from the sensor); leave the base with the "
        "Hall sensor and the drive coils in place: the coils are driven during the background "
        "recording.");
    items.push_back("Hall MCU connected (USB).");
    if (before_step1) {
      items.push_back("Keep the MSM out of the beam path: step 1 (" +
                      std::to_string(plan.step1.size()) +
                      " frames) runs with the MSM not mounted; the background Hall recording "
                      "follows it without another prompt.");
      return Header(number, total, "Before step 1: background Hall recording set-up") +
             Numbered(items);
    }
    items.push_back(
        "Do not touch the rig while it records: the background Hall recording starts "
        "as soon as you confirm.");
    return Header(number, total, "Step 1 done: background Hall recording") + Numbered(items);
  }
  items = {"Mount the mirror's top frame (MSM assembled, magnet over the Hall sensor).",
           "Put the MSM in the beam path, remove the sliding plate and move the camera to the "
           "step-2 position (it sees the world board with the reflected dots).",
           "The actual Hall recording runs during the whole of step 2 (" +
               std::to_string(plan.step2.size()) + " frames)."};
  return Header(number, total, "Step 2 set-up: actual Hall recording") + Numbered(items);
}

std::string DescribeStep1Frame(const dataset::Recording& plan, size_t index,
                               const std::vector<std::string>& pose_hints, int number, int total) {
  const dataset::Step1Frame& f = plan.step1.at(index);
  const int poses = PoseCount(plan);
  std::vector<std::string> items;
  items.push_back("MSM not mounted: the beams go straight to the sliding plate.");
  std::string where = "pose " + std::to_string(f.pose + 1) + " of " + std::to_string(poses);
  if (f.pose >= 0 && static_cast<size_t>(f.pose) < pose_hints.size() && !pose_hints[f.pose].empty())
    where += " (" + pose_hints[f.pose] + ")";
  const bool same_pose = index > 0 && plan.step1[index - 1].pose == f.pose;
  auto sorted = [](std::vector<int> v) {
    std::sort(v.begin(), v.end());
    return v;
  };
  if (same_pose && sorted(plan.step1[index - 1].beams) == sorted(f.beams)) {
    items = {"MSM not mounted.", "Another exposure of the same scene: change nothing (plate at " +
                                     where + ", " + BeamsLine(plan, f.beams) +
                                     " The solver averages repeated exposures.)"};
    return Header(number, total,
                  "Step 1, frame " + std::to_string(index + 1) + " of " +
                      std::to_string(plan.step1.size()) + " (" + f.file + ")") +
           Numbered(items);
  }
  items.push_back(same_pose    ? "Leave the sliding plate at " + where + "."
                  : index == 0 ? "Mount the sliding plate at " + where + "."
                               : "Move the sliding plate to " + where + ".");
  items.push_back("Both boards (sliding plate and world board) fully visible to the camera.");
  items.push_back(BeamsLine(plan, f.beams));
  return Header(number, total,
                "Step 1, frame " + std::to_string(index + 1) + " of " +
                    std::to_string(plan.step1.size()) + " (" + f.file + ")") +
         Numbered(items);
}

std::string DescribeStep2Frame(const dataset::Recording& plan, size_t index, int number,
                               int total) {
  const dataset::Step2Frame& f = plan.step2.at(index);
  std::vector<std::string> items;
  items.push_back("MSM mounted (top frame on), camera at the step-2 position.");
  switch (f.kind) {
    case dataset::Step2Kind::kNeutral:
      items.push_back("Neutral frame: drives off (fast and slow axis at rest).");
      break;
    case dataset::Step2Kind::kFastOnly:
      items.push_back("Fast-only frame: fast axis driven, slow drive off.");
      break;
    case dataset::Step2Kind::kScan:
      items.push_back("Scan frame: both drives on (full scan).");
      break;
  }
  if (f.triggers.empty()) {
    items.push_back("Laser: continuous reference exposure (no trigger selection).");
  } else {
    std::ostringstream t;
    t << "Laser pulses of trigger" << (f.triggers.size() == 1 ? " j = " : "s j = ")
      << JoinInts(f.triggers) << " (t = ";
    for (size_t i = 0; i < f.triggers.size(); ++i) {
      double t_s = -1;
      for (const auto& tr : plan.triggers)
        if (tr.j == f.triggers[i]) t_s = tr.t_s;
      char buf[32];
      std::snprintf(buf, sizeof(buf), "%.3f", t_s * 1e3);
      t << (i ? ", " : "") << buf;
    }
    t << " ms in the pattern period).";
    items.push_back(t.str());
  }
  items.push_back(BeamsLine(plan, f.beams));
  return Header(number, total,
                "Step 2, frame " + std::to_string(index + 1) + " of " +
                    std::to_string(plan.step2.size()) + ", " + dataset::ToString(f.kind) + " (" +
                    f.file + ")") +
         Numbered(items);
}

ConsoleOperator::ConsoleOperator(const dataset::Recording& plan, ConsoleOperatorOptions options,
                                 RigOperator* inner)
    : plan_(plan), options_(std::move(options)), inner_(inner) {
  if (std::string e = options_.Validate(inner_ != nullptr); !e.empty())
    throw std::invalid_argument(e);
  total_ = static_cast<int>(2 + plan_.step1.size() + plan_.step2.size());
}

void ConsoleOperator::Write(const std::string& text) const {
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(options_.output_fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw OperatorAbort(std::string("guided mode: cannot write to the terminal: ") +
                          std::strerror(errno));
    done += static_cast<size_t>(n);
  }
}

bool ConsoleOperator::ReadLine(std::string* line) {
  for (;;) {
    const size_t nl = pending_.find('\n');
    if (nl != std::string::npos) {
      *line = pending_.substr(0, nl);
      pending_.erase(0, nl + 1);
      if (!line->empty() && line->back() == '\r') line->pop_back();
      return true;
    }
    char buf[256];
    const ssize_t n = ::read(options_.input_fd, buf, sizeof(buf));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;  // EOF, or the terminal went away (EIO on a closed pty)
    pending_.append(buf, static_cast<size_t>(n));
  }
}

void ConsoleOperator::Ask(const std::string& instructions) {
  Write(instructions);
  for (;;) {
    Write(kConsolePrompt);
    std::string line;
    if (!ReadLine(&line)) {
      Write("\n");
      throw OperatorAbort("guided mode: input ended at a prompt (operator gone): session aborted");
    }
    // Trim blanks.
    const size_t b = line.find_first_not_of(" \t");
    line = b == std::string::npos ? "" : line.substr(b, line.find_last_not_of(" \t") - b + 1);
    if (line.empty()) break;
    if (line == "r" || line == "R") {
      Write(instructions);
      continue;
    }
    if (line == "q" || line == "Q" || line == "quit" || line == "abort")
      throw OperatorAbort("guided mode: operator aborted the session at a prompt");
    Write("unknown answer '" + line + "'\n");
  }
  ++confirmations_;
  Write("ok.\n");
}

void ConsoleOperator::SeeFirstCall(bool is_background) {
  if (order_known_) return;
  order_known_ = true;
  background_first_ = is_background;
}

int ConsoleOperator::Step1Number(size_t index) const {
  return static_cast<int>(index) + (background_first_ ? 2 : 1);
}

void ConsoleOperator::PrepareStep1Frame(size_t index) {
  SeeFirstCall(false);
  Ask(DescribeStep1Frame(plan_, index, options_.pose_hints, Step1Number(index), total_));
  if (inner_)
    inner_->PrepareStep1Frame(index);
  else
    confirmed_ns_ = options_.host_clock_ns();
}

void ConsoleOperator::PrepareStep2Frame(size_t index) {
  SeeFirstCall(false);
  Ask(DescribeStep2Frame(plan_, index, static_cast<int>(3 + plan_.step1.size() + index), total_));
  if (inner_)
    inner_->PrepareStep2Frame(index);
  else
    confirmed_ns_ = options_.host_clock_ns();
}

bool ConsoleOperator::FrameShowsCurrentSetup(const camera::FrameInfo& info) const {
  if (inner_) return inner_->FrameShowsCurrentSetup(info);
  return info.host_timestamp_ns - confirmed_ns_ >= options_.settle_ns;
}

std::string ConsoleOperator::PrepareHallRecording(HallRun run) {
  SeeFirstCall(run == HallRun::kBackground);
  const int n1 = static_cast<int>(plan_.step1.size());
  const int number = run == HallRun::kActual ? 2 + n1 : (background_first_ ? 1 : 1 + n1);
  Ask(DescribeHallRecording(plan_, run, background_first_, number, total_));
  if (inner_) return inner_->PrepareHallRecording(run);
  confirmed_ns_ = options_.host_clock_ns();
  return options_.mcu_device;
}

std::string FormatLiveFigures(const FrameReport& report, const LiveTotals& totals) {
  std::ostringstream s;
  s << "  live: " << report.file << " (step " << report.step << ", " << report.index + 1 << "/"
    << report.count << ", attempt " << report.attempt + 1 << "): ";
  if (const GateResult* g = report.gate) {
    const char* names1[] = {"sliding board", "world board"};
    for (size_t b = 0; b < g->boards.size(); ++b) {
      const char* name = report.step == 1 && b < 2 ? names1[b] : "world board";
      s << name << (g->boards[b] ? " found" : " NOT found") << ", ";
    }
    char buf[64];
    std::snprintf(buf, sizeof(buf), "saturated %.2f%%, ", 100.0 * g->saturated_fraction);
    s << "dots " << g->dots_found << "/" << g->dots_expected << ", " << buf;
  } else {
    s << "(quality gate off), ";
  }
  if (report.accepted) {
    s << "ACCEPTED";
  } else {
    s << (report.final ? "REJECTED: " : "retry: ")
      << (report.gate ? report.gate->reason : std::string("not accepted"));
  }
  s << " | totals: " << totals.accepted << " accepted, " << totals.rejected << " rejected, "
    << totals.retried << " retried";
  return s.str();
}

FrameObserver MakeLiveFigures(std::function<void(const std::string& line)> print) {
  auto totals = std::make_shared<LiveTotals>();
  return [print = std::move(print), totals](const FrameReport& r) {
    if (r.accepted)
      ++totals->accepted;
    else if (r.final)
      ++totals->rejected;
    else
      ++totals->retried;
    print(FormatLiveFigures(r, *totals));
  };
}

}  // namespace msmcal::orchestrator
