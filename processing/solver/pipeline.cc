#include "processing/solver/pipeline.h"

#include <map>
#include <memory>
#include <sstream>
#include <utility>

#include "processing/solver/stages/common.h"
#include "processing/solver/stages/estimate.h"
#include "processing/solver/stages/exposures.h"
#include "processing/solver/stages/mirror0.h"
#include "processing/solver/stages/step1_beams.h"
#include "processing/solver/stages/step2_groups.h"
#include "processing/solver/stages/uncertainty.h"
#include "processing/solver/stages/validation.h"

namespace msmcal::solver {

std::string PipelineOptions::Validate() const {
  if (std::string e = dots.Validate(); !e.empty()) return "dots." + e;
  if (std::string e = boards.Validate(); !e.empty()) return "boards." + e;
  if (std::string e = mle.Validate(); !e.empty()) return "mle." + e;
  std::ostringstream s;
  if (!(step1_dot_margin_squares >= 0 && step1_dot_margin_squares <= 1000))
    s << "step1_dot_margin_squares = " << step1_dot_margin_squares << " must be in [0, 1000]";
  else if (!(step2_dot_margin_squares >= 0 && step2_dot_margin_squares <= 1000))
    s << "step2_dot_margin_squares = " << step2_dot_margin_squares << " must be in [0, 1000]";
  else if (!(max_surface_elongation >= 1 && max_surface_elongation <= 100))
    s << "max_surface_elongation = " << max_surface_elongation << " must be in [1, 100]";
  else if (!(junction_elongation >= 1))
    s << "junction_elongation = " << junction_elongation << " must be >= 1";
  else if (!(junction_exclusion_squares >= 0 && junction_exclusion_squares <= 1))
    s << "junction_exclusion_squares = " << junction_exclusion_squares << " must be in [0, 1]";
  else if (!(adaptive_min_relative_peak >= 0 && adaptive_min_relative_peak < 1))
    s << "adaptive_min_relative_peak = " << adaptive_min_relative_peak << " must be in [0, 1)";
  else if (!(static_blob_radius_px >= 0 && static_blob_radius_px <= 100))
    s << "static_blob_radius_px = " << static_blob_radius_px << " must be in [0, 100]";
  else if (max_surplus_dots < 0 || max_surplus_dots > 50)
    s << "max_surplus_dots = " << max_surplus_dots << " must be in [0, 50]";
  else if (!(max_group_residual_px > 0))
    s << "max_group_residual_px = " << max_group_residual_px << " must be > 0";
  else if (!(partial_frame_group_residual_px > 0))
    s << "partial_frame_group_residual_px = " << partial_frame_group_residual_px << " must be > 0";
  else if (ransac_iterations < 1)
    s << "ransac_iterations = " << ransac_iterations << " must be >= 1";
  else if (!(ransac_inlier_deg > 0))
    s << "ransac_inlier_deg = " << ransac_inlier_deg << " must be > 0";
  else if (image_threads < 1)
    s << "image_threads = " << image_threads << " must be >= 1";
  return s.str();
}

// The method of MSM paper Sec. V-A as its stages (docs/solver.md, "Stages"): each stage takes
// values and returns one, with the frames it dropped and what it noted (StageLog); a stage
// that cannot go on ends the solve with SolveError, carrying everything decided so far.
SolveOutput SolveRecording(const dataset::Recording& input, const ImageLoader& input_load,
                           const PipelineOptions& options) {
  if (const std::string e = options.Validate(); !e.empty())
    throw SolveError("PipelineOptions: " + e);
  if (const std::string e = input.camera.Validate(); !e.empty())
    throw SolveError("camera.yaml: " + e);
  SolveOutput out;
  // Repeated exposures of a scene become one averaged frame (stages/exposures.h).
  const ExposureScenes exposures =
      options.average_exposures ? CollapseExposures(input) : ExposureScenes{};
  if (exposures.Collapsed()) out.notes.push_back(exposures.Note());
  const dataset::Recording& rec = exposures.Collapsed() ? exposures.recording : input;
  const ImageLoader load = [&](const std::string& file) {
    return LoadScene(exposures, input_load, file);
  };
  // Per measured (collapsed) frame: what was measured and decided (results/detections.csv).
  std::vector<FrameDetection> det;
  // Expands `det` to one row per frame of the input (exposures share their scene's row) and
  // marks the dropped ones.
  auto finish_detections = [&](SolveOutput* o_out) {
    std::map<std::string, std::string> dropped_reason;
    for (const auto& d : out.dropped) dropped_reason.emplace(d.file, d.reason);
    std::map<std::string, const FrameDetection*> by_scene;
    for (const auto& d : det) by_scene[d.file] = &d;
    o_out->detections.clear();
    auto add = [&](const std::string& file, const std::string& step) {
      const std::string scene = exposures.SceneOf(file);
      FrameDetection d;
      if (const auto it = by_scene.find(scene); it != by_scene.end()) d = *it->second;
      d.file = file;
      d.step = step;
      d.scene = scene;
      if (const auto it = dropped_reason.find(scene); it != dropped_reason.end()) {
        // "... frame used for the sliding board only": used in part.
        if (it->second.find("used for the sliding board only") != std::string::npos) {
          d.used = true;
          d.partial = true;
          d.note = it->second;
        } else {
          d.used = false;
          d.reason = it->second;
        }
      } else if (d.dots_found >= 0) {
        d.used = true;
      } else if (d.reason.empty()) {
        d.used = false;
        d.reason = "not reached: the solve stopped before this frame was used";
      }
      o_out->detections.push_back(std::move(d));
    };
    for (const auto& f : input.step1) add(f.file, "step1");
    for (const auto& f : input.step2) add(f.file, "step2");
  };
  // Errors carry the frames dropped so far (they usually explain the failure) and the
  // detections up to the failure.
  auto fail = [&](const std::string& what) {
    std::string msg = what;
    if (!out.dropped.empty()) {
      msg += "; frames dropped:";
      for (const auto& d : out.dropped) msg += " [" + d.file + ": " + d.reason + "]";
    }
    auto partial = std::make_shared<SolveOutput>();
    partial->dropped = out.dropped;
    partial->notes = out.notes;
    finish_detections(partial.get());
    return SolveError(msg, partial);
  };
  // A stage's dropped frames and notes join the solve's; its error ends it.
  auto absorb = [&](StageLog log) {
    for (auto& d : log.dropped) out.dropped.push_back(std::move(d));
    for (auto& n : log.notes) out.notes.push_back(std::move(n));
    if (!log.error.empty()) throw fail(log.error);
  };
  const BeamTable beams = MakeBeamTable(rec.beams);

  // Boards and laser dots of every image (stages/measure.h).
  RecordingMeasurement measured = MeasureRecording(rec, load, options);
  det = std::move(measured.detections);
  absorb(std::move(measured.log));
  // The later stages look for dots where the measurement found them (dot_margin_from_data).
  PipelineOptions o = options;
  o.step1_dot_margin_squares = measured.step1_dot_margin_squares;
  o.step2_dot_margin_squares = measured.step2_dot_margin_squares;

  // ---------------- Step 1: sliding boards, beams (Sec. V-A1) ----------------
  // The sliding plate's poses and its dots in {W}, then the dots' beams and the beams (eq. 2).
  Step1Frames step1 = MeasureStep1Frames(rec, measured.images, std::move(det), beams, o);
  det = std::move(step1.detections);
  absorb(std::move(step1.log));
  BeamLabels labelled = LabelBeams(step1.views, step1.world_from_pose, step1.sliding_z, beams);
  absorb(std::move(labelled.log));

  // ---------------- Step 2: world board, reflected dots, groups (Sec. V-A2) ----------------
  // The reflected dots in {W}, grouped into one mirror plane per trigger (eq. 3).
  Step2Frames step2 = MeasureStep2Frames(rec, measured.images, std::move(det), o);
  det = std::move(step2.detections);
  absorb(std::move(step2.log));
  ReflectionGroups grouped =
      GroupReflections(step2.views, labelled.beams, beams, rec.camera, *step2.c2_from_world, o);
  for (size_t i = 0; i < step2.views.size(); ++i)
    if (!grouped.partial_note[i].empty()) {
      FrameDetection& fd = det[rec.step1.size() + step2.views[i].index];
      fd.partial = true;
      fd.note = grouped.partial_note[i];
    }
  absorb(std::move(grouped.log));
  // Which trigger each plane of a multi-trigger frame belongs to (drive-phase model), then one
  // mirror plane per (kind, trigger index).
  TriggerAssignment assigned =
      AssignTriggerSlots(step2.views, std::move(grouped.groups), std::move(grouped.recovered),
                         rec.triggers, rec.drive, o);
  for (const int v : assigned.off_model) {
    FrameDetection& fd = det[rec.step1.size() + step2.views[v].index];
    fd.partial = true;
    const std::string why = "a mirror plane off the drive-phase model left out";
    if (fd.note.find(why) == std::string::npos)
      fd.note = fd.note.empty() ? why : fd.note + "; " + why;
  }
  absorb(std::move(assigned.log));
  MirrorPlanes planes = CollectMirrorPlanes(step2.views, assigned.groups, beams);
  out.num_neutral_planes = planes.num_neutral;
  out.num_fast_only_planes = planes.num_fast_only;
  out.num_scan_planes = planes.num_scan;
  absorb(std::move(planes.log));

  // ---------------- Estimation (Sec. V-A4, eqs. 4-8) ----------------
  Observations obs;
  obs.camera = rec.camera;
  obs.num_poses = step1.num_poses;
  obs.num_beams = beams.size();
  obs.num_planes = static_cast<int>(planes.keys.size());
  obs.corners = step1.corners;
  obs.corners.insert(obs.corners.end(), step2.corners.begin(), step2.corners.end());
  std::vector<std::vector<char>> corners_clear = step1.corners_clear;
  corners_clear.insert(corners_clear.end(), step2.corners_clear.begin(), step2.corners_clear.end());
  obs.sliding_dots = labelled.sliding_dots;
  obs.reflected_dots = planes.estimate_dots;
  MleEstimate estimate = EstimateMle(std::move(obs), corners_clear, o.mle);
  absorb(std::move(estimate.log));
  out.mle = std::move(estimate.mle);

  // {0} (Sec. V-A3, eq. 11), its uncertainty, and the scan planes' poses in it.
  const Mirror0 mirror0 = EstimateMirror0(planes.keys, out.mle);
  out.world_from_mirror0 = mirror0.world_from_mirror0;
  out.support_planes = mirror0.support_planes;
  const Mirror0Covariance mirror0_cov =
      PropagateMirror0Covariance(mirror0.roles, out.mle, out.world_from_mirror0);
  out.mirror0_cov = mirror0_cov.cov;
  out.planes = ScanPlaneRows(planes.keys, mirror0.roles, rec.triggers, out.mle,
                             out.world_from_mirror0, mirror0_cov);
  out.beams = BeamRows(out.mle.estimate.beams, beams.ids, out.world_from_mirror0.translation);
  std::vector<int> estimate_beams;
  for (int b = 0; b < beams.size(); ++b)
    if (beams.is_estimate[b]) estimate_beams.push_back(b);
  out.mean_spanning_angle_deg =
      MeanSpanningAngleDeg(estimate.obs.reflected_dots, ScanPlanesByJ(planes.keys, mirror0.roles),
                           estimate_beams, rec.camera, out.mle.estimate);

  // ---------------- Validation on held-out beams (Sec. V-B, Table I) ----------------
  ValidationResult validation = ValidateHeldOutBeams(
      estimate.obs, planes.validation_dots, planes.keys, estimate_beams, beams.ids, out.mle);
  out.baseline = std::move(validation.baseline);
  out.validation = std::move(validation.details);
  out.rms_validation_deg = validation.rms_deg;
  out.rms_validation_px = validation.rms_px;
  out.rms_baseline_deg = validation.rms_baseline_deg;
  out.rms_baseline_px = validation.rms_baseline_px;
  out.rms_normalised_validation = validation.rms_normalised;
  out.residuals = WhitenedFitResiduals(estimate.obs, out.mle);
  finish_detections(&out);
  return out;
}

}  // namespace msmcal::solver
