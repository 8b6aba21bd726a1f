#pragma once
// `msmcal solve DIR --config solve.yaml`: every detection and gating knob of the solver as a YAML
// file, read into solver::PipelineOptions and validated before any image is read, and written
// back (the values actually used) into results/solve_options.yaml so that a run can be
// repeated. Unknown keys are errors (a misspelt knob must not be silently ignored).
//
// Errors: std::runtime_error "solve.yaml:12: dots.min_pixels: expected an integer, got 'x'" or
// "solve.yaml: dots.min_pixels = 0 violates: must be >= 1".

#include <string>

#include "processing/solver/pipeline.h"

namespace msmcal::results {

// Reads `path` over `defaults` (keys absent from the file keep their default).
solver::PipelineOptions ReadSolveOptions(const std::string& path,
                                         const solver::PipelineOptions& defaults = {});
// The YAML text of `options`, every knob, commented with its meaning.
std::string FormatSolveOptions(const solver::PipelineOptions& options);

}  // namespace msmcal::results
