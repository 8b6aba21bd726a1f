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
namespace {}  // namespace

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

namespace {

// What the set-up walk needs of the console's options (validated first).
SetupWalkOptions WalkOf(const ConsoleOperatorOptions& o, bool has_inner) {
  if (std::string e = o.Validate(has_inner); !e.empty()) throw std::invalid_argument(e);
  return {o.poses, o.mcu_device, o.host_clock_ns, o.settle_ns, o.exposure_ns};
}

}  // namespace

ConsoleOperator::ConsoleOperator(const dataset::Recording& plan, ConsoleOperatorOptions options,
                                 RigOperator* inner)
    : SetupOperator(plan, WalkOf(options, inner != nullptr), inner), options_(std::move(options)) {}

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

void ConsoleOperator::Present(const setup::Setup& s) {
  const std::string& instructions = s.text;
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
  Write("ok.\n");
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
