#pragma once
// The whole mirror-pose solve of an interchange recording (MSM paper Sec. V-A): boards and dots
// in every image, association of dots to beams, sliding poses and trigger indices, initial
// values, the MLE with per-plane covariance, the mirror home frame {0}, validation on held-out
// beams and the baseline model of Table I. Pure computation: images come through `ImageLoader`,
// results go back as values (the CLI writes results/).
//
// Failure model: bad or insufficient input throws SolveError naming the file and what is wrong
// ("step1/0003.png: sliding board (13x8) not found"); frames that cannot be used but are not
// needed are dropped and listed in SolveOutput::dropped with the reason.

// The stages, one header each under stages/ (docs/solver.md, "Stages"): exposures, measure,
// step1_beams, step2_groups, triggers, estimate, mirror0, uncertainty, validation.

#include "processing/dataset/recording.h"
#include "processing/solver/solve_types.h"
#include "processing/solver/stages/measure.h"
#include "processing/solver/stages/triggers.h"

namespace msmcal::solver {

SolveOutput SolveRecording(const dataset::Recording& recording, const ImageLoader& load,
                           const PipelineOptions& options = {});

}  // namespace msmcal::solver
