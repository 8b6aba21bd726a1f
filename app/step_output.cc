#include "app/step_output.h"

#include <spdlog/spdlog.h>

#include <cstdio>
#include <fstream>

namespace msmcal::app {

void PrintStepReport(const results::StepReport& report) {
  for (const auto& w : report.warnings) std::fprintf(stderr, "%s\n", w.c_str());
  for (const auto& l : report.log) {
    if (l.level == results::StepLogLine::Level::kWarning)
      spdlog::warn("{}", l.text);
    else
      spdlog::info("{}", l.text);
  }
  std::printf("%s", report.text.c_str());
  std::fflush(stdout);
}

void AppendStepReport(const results::StepReport& report, const std::filesystem::path& log_file) {
  std::ofstream out(log_file, std::ios::app);
  if (!out) return;
  for (const auto& w : report.warnings) out << w << '\n';
  for (const auto& l : report.log)
    out << (l.level == results::StepLogLine::Level::kWarning ? "[warning] " : "[info] ") << l.text
        << '\n';
  out << report.text;
  if (!report.ok()) out << "[error] " << report.error << '\n';
}

}  // namespace msmcal::app
