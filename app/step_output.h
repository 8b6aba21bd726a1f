#pragma once
// How the command line shows a finish step's report (sessions/results/finish_steps.h): the same
// for `msmcal solve` / `msmcal hall ...` and for the session modes that run the steps in-process.

#include <filesystem>

#include "sessions/results/finish_steps.h"

namespace msmcal::app {

// Warnings on stderr, log lines through spdlog, then the text on stdout (flushed). Not the error
// of a failed step: the commands throw it (`main` logs it at error level and exits with 1).
void PrintStepReport(const results::StepReport& report);
// The same lines appended to `log_file` (spdlog lines as "[info] ...", the error as
// "[error] ..."); a log that cannot be opened is skipped.
void AppendStepReport(const results::StepReport& report, const std::filesystem::path& log_file);

}  // namespace msmcal::app
