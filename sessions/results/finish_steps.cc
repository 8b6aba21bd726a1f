#include "sessions/results/finish_steps.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <exception>
#include <memory>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <sstream>
#include <stdexcept>

#include "processing/solver/diagnostics.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/results/solve_options_io.h"

namespace msmcal::results {

namespace fs = std::filesystem;

namespace {

double SecondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Reads the folder's images; each one must be what `msmcal interchange check` accepts (8/16-bit
// mono or BGR of camera.yaml's image_size), else the solve stops naming the file.
solver::ImageLoader FolderLoader(const fs::path& dir, const geometry::CameraModel& camera) {
  return [dir, camera](const std::string& file) {
    cv::Mat image = cv::imread((dir / file).string(), cv::IMREAD_UNCHANGED);
    if (image.empty()) return image;  // the solver reports an unreadable image itself
    if (std::string problem = interchange::ImageProblem(image, camera); !problem.empty())
      throw solver::SolveError(file + ": " + problem);
    return image;
  };
}

// results/detections.csv, results/diagnostics/*.jpg (dropped and partly used frames); the drop
// summary with its hint goes to `warnings`.
void WriteDiagnostics(const fs::path& dir, const std::vector<solver::FrameDetection>& detections,
                      std::vector<std::string>* warnings) {
  const fs::path results = dir / "results";
  interchange::WriteFileAtomically(results / "detections.csv",
                                   solver::FormatDetectionsCsv(detections));
  const fs::path diag = results / "diagnostics";
  std::error_code ec;
  fs::remove_all(diag, ec);
  int written = 0;
  for (const auto& d : detections) {
    if (d.used && !d.partial) continue;
    const cv::Mat img = cv::imread((dir / d.file).string(), cv::IMREAD_UNCHANGED);
    if (img.empty()) continue;
    fs::create_directories(diag);
    std::string name = d.file;
    for (char& c : name)
      if (c == '/' || c == '\\') c = '_';
    name = name.substr(0, name.rfind('.')) + ".jpg";
    if (cv::imwrite((diag / name).string(), solver::AnnotateFrame(img, d),
                    {cv::IMWRITE_JPEG_QUALITY, 85}))
      ++written;
  }
  const solver::DropSummary sum = solver::SummariseDrops(detections);
  if (sum.dropped > 0 || sum.partial > 0) {
    std::string w = "frames: " + std::to_string(sum.dropped) + " of " + std::to_string(sum.frames) +
                    " dropped, " + std::to_string(sum.partial) + " used in part";
    if (sum.dropped > 0)
      w += "; most common reason (" + std::to_string(sum.common_count) + "): " + sum.common_reason +
           "\nhint: " + sum.hint;
    w += "\nper-frame figures: " + (results / "detections.csv").string() + "; annotated frames (" +
         std::to_string(written) + "): " + diag.string();
    warnings->push_back(w);
  }
}

void AddDropped(const std::vector<solver::DroppedFrame>& dropped,
                std::vector<std::string>* warnings) {
  for (const auto& d : dropped) warnings->push_back("dropped " + d.file + ": " + d.reason);
}

// The printf text of `format` (the command line's figures are printf-formatted).
[[gnu::format(printf, 1, 2)]] std::string Printf(const char* format, ...) {
  va_list args;
  va_start(args, format);
  va_list copy;
  va_copy(copy, args);
  const int n = std::vsnprintf(nullptr, 0, format, copy);
  va_end(copy);
  std::string s(static_cast<size_t>(std::max(n, 0)), '\0');
  std::vsnprintf(s.data(), s.size() + 1, format, args);  // the '\0' goes to s's terminator
  va_end(args);
  return s;
}

// Which part of the actual recording the calibration used (processing/hall/driven_periods.h).
std::string ActualPeriodsLine(const hall::DrivenPeriods& p, size_t readings) {
  if (p.readings_used == readings) return {};
  return Printf(
      "actual recording: %zu of %zu readings used, %d of %d pattern periods with both drives "
      "running (%d with a drive off, e.g. neutral and fast-only frames, %d next to them left "
      "out)\n",
      p.readings_used, readings, p.driven, p.periods, p.not_driven, p.margin);
}

}  // namespace

SolveStepResult RunSolveStep(const fs::path& dir, const solver::PipelineOptions& options,
                             const std::function<void(size_t, size_t)>& on_image) {
  SolveStepResult r;
  try {
    if (const std::string e = options.Validate(); !e.empty())
      throw std::runtime_error("solve settings: " + e);
    const dataset::Recording rec = interchange::ReadRecordingForSolve(dir);
    const fs::path results = dir / "results";
    interchange::WriteFileAtomically(results / "solve_options.yaml", FormatSolveOptions(options));
    const auto t0 = std::chrono::steady_clock::now();
    solver::SolveOutput out;
    try {
      solver::ImageLoader load = FolderLoader(dir, rec.camera);
      if (on_image) {
        struct Seen {
          std::mutex mu;
          std::set<std::string> files;
        };
        auto seen = std::make_shared<Seen>();
        const size_t total = rec.step1.size() + rec.step2.size();
        load = [inner = std::move(load), seen, total, &on_image](const std::string& file) {
          cv::Mat image = inner(file);
          size_t n = 0;
          {
            std::lock_guard<std::mutex> lock(seen->mu);
            seen->files.insert(file);
            n = seen->files.size();
          }
          on_image(n, total);
          return image;
        };
      }
      out = solver::SolveRecording(rec, load, options);
    } catch (const solver::SolveError& e) {
      if (e.partial) {
        AddDropped(e.partial->dropped, &r.warnings);
        WriteDiagnostics(dir, e.partial->detections, &r.warnings);
      }
      throw;
    }
    const double solve_s = SecondsSince(t0);
    AddDropped(out.dropped, &r.warnings);
    WriteMirrorPlanesCsv(results / "mirror_planes.csv", out.planes);
    WriteBeamsCsv(results / "beams.csv", out.beams);
    std::vector<dataset::ValidationRow> rows;
    for (const auto& v : out.validation) rows.push_back(v.row);
    WriteValidationCsv(results / "validation.csv", rows);
    WriteValidationDetailCsv(results / "validation_detail.csv",
                             ValidationDetailRows(out.validation));
    WriteValidationDotsCsv(results / "validation_dots.csv", ValidationDotRows(out.validation));
    WriteResidualsCsv(results / "residuals.csv", out.residuals);
    r.summary = SummariseSolve(out, solve_s);
    WriteMirrorPosesSummary(results / "summary.json", r.summary);
    WriteDiagnostics(dir, out.detections, &r.warnings);
    // A Hall model from an earlier solve was fitted to other poses (a re-solve with other
    // settings): it stays, but the user is told to fit it again.
    if (fs::exists(results / "hall_model.yaml"))
      r.warnings.push_back(
          "results/hall_model.yaml (and summary.json \"hall\") were fitted to an "
          "earlier solve's mirror poses: run `msmcal hall calibrate " +
          dir.string() + "` again to fit them to these");
    r.text = Printf(
        "solved %d scan planes (%d fast-only, %d neutral), %zu beams in %.1f s\n"
        "validation: proposed %.4f deg RMS (%.3f px), baseline %.4f deg RMS, normalised %.2f, "
        "mean spanning angle %.1f deg\n",
        out.num_scan_planes, out.num_fast_only_planes, out.num_neutral_planes, out.beams.size(),
        solve_s, out.rms_validation_deg, out.rms_validation_px, out.rms_baseline_deg,
        out.rms_normalised_validation, out.mean_spanning_angle_deg);
  } catch (const std::exception& e) {
    r.error = e.what();
  }
  return r;
}

HallCalibrationSetup MakeHallCalibrationSetup(const dataset::Recording& rec,
                                              const std::vector<dataset::MirrorPlaneRow>& planes,
                                              const std::string& dir) {
  if (!rec.hall_actual)
    throw std::runtime_error(dir +
                             "/hall/actual.csv: missing (the Hall recording made during the scan)");
  if (!rec.hall_background)
    throw std::runtime_error(
        dir +
        "/hall/background.csv: missing (the Hall recording with the mirror's top frame removed)");
  if (planes.empty())
    throw std::runtime_error(dir + "/results/mirror_planes.csv: no mirror planes");
  HallCalibrationSetup s;
  s.actual = *rec.hall_actual;
  s.background = *rec.hall_background;
  s.pattern_period_s = rec.drive.pattern_period_s;
  s.fast_frequency_hz = rec.drive.fast.frequency_hz;
  s.slow_frequency_hz = rec.drive.slow.frequency_hz;
  for (const auto& p : planes) {
    hall::PoseSample ps;
    ps.t_s = p.t_s;
    ps.pose = Eigen::Vector3d(p.alpha_deg, p.beta_deg, p.trans_mm);
    ps.sigma = Eigen::Vector3d(p.sigma_alpha_deg, p.sigma_beta_deg, p.sigma_trans_mm);
    s.poses.push_back(ps);
  }
  return s;
}

hall::HallCalibrationInput HallCalibrationSetup::Input() const {
  hall::HallCalibrationInput in;
  in.actual = &actual;
  in.background = &background;
  in.pattern_period_s = pattern_period_s;
  in.fast_frequency_hz = fast_frequency_hz;
  in.slow_frequency_hz = slow_frequency_hz;
  in.poses = poses;
  return in;
}

std::string FormatTableTwo(const hall::HallCalibrationResult& r,
                           const hall::HallCalibrationOptions& o) {
  std::ostringstream s;
  char line[256];
  if (r.leave_one_out)
    std::snprintf(line, sizeof line,
                  "Table II (leave-one-out over %d poses, fewer than the %d that random %.0f:%.0f "
                  "splits need; RMS +- std over the held-out poses)\n",
                  r.repetitions, r.min_poses_for_splits, o.train_fraction * 10,
                  (1 - o.train_fraction) * 10);
  else
    std::snprintf(line, sizeof line,
                  "Table II (%d random %.0f:%.0f train/test splits, RMS +- std over splits)\n",
                  r.repetitions > 0 ? r.repetitions : o.repetitions, o.train_fraction * 10,
                  (1 - o.train_fraction) * 10);
  s << line;
  std::snprintf(line, sizeof line, "%-10s %20s %20s %20s %14s\n", "model", "alpha (deg)",
                "beta (deg)", "trans (mm)", "dt (ms)");
  s << line;
  for (const auto& m : r.table) {
    std::snprintf(line, sizeof line,
                  "%-10s %10.4f +- %6.4f %10.4f +- %6.4f %10.4f +- %6.4f %8.4f%s\n",
                  hall::ToString(m.kind), m.test_rms_mean[0], m.test_rms_std[0], m.test_rms_mean[1],
                  m.test_rms_std[1], m.test_rms_mean[2], m.test_rms_std[2], m.delta_t_mean_s * 1e3,
                  m.kind == r.best ? "  <- best" : "");
    s << line;
  }
  for (const auto& skipped : r.skipped_models) s << "left out: " << skipped << "\n";
  s << "paper (sine): 0.083 +- 0.040 deg, 0.069 +- 0.040 deg, 0.10 +- 0.08 mm\n";
  return s.str();
}

std::string FormatDeltaT(const hall::DeltaTEstimate& e, hall::HallModelKind model,
                         double model_delta_t_s, bool in_field_valley) {
  std::string own;
  if (e.model != model) {
    const std::string kept =
        in_field_valley ? Printf(", kept in the %s model's valley,", hall::ToString(e.model)) : "";
    own = Printf("; the %s model's own dt %.4f ms%s aligns phases, not clocks",
                 hall::ToString(model), model_delta_t_s * 1e3, kept.c_str());
  }
  if (!e.identified())
    return Printf("delta_t not identified (%s: %s%s)", hall::ToString(e.status), e.reason.c_str(),
                  own.c_str());
  if (e.method == hall::DeltaTMethod::kDrivePhases)
    return Printf(
        "delta_t = %.4f ms +- %.4f ms (identified by the drives' phases; the %s model's profile "
        "did not: %s: %s%s)",
        e.delta_t_s * 1e3, e.sigma_s * 1e3, hall::ToString(e.model), hall::ToString(e.field_status),
        e.field_reason.c_str(), own.c_str());
  std::string next = std::isnan(e.separation)
                         ? std::string("no other minimum in the window")
                         : Printf("next minimum at %.3f ms, %.1f residual variances higher",
                                  e.runner_up_s * 1e3, e.separation);
  return Printf("delta_t = %.4f ms +- %.4f ms (%s model, identified: %d of %d splits agree, %s%s)",
                e.delta_t_s * 1e3, e.sigma_s * 1e3, hall::ToString(e.model), e.splits_agreeing,
                e.splits, next.c_str(), own.c_str());
}

std::string FormatDrivePhase(const hall::DrivePhaseEstimate& e, hall::DeltaTBracket bracket) {
  const char* brackets =
      bracket == hall::DeltaTBracket::kDrivePhases ? "; it brackets the final fit" : "";
  if (!e.determined)
    return "drive phases: dt not determined (" + e.reason + ")" +
           (bracket == hall::DeltaTBracket::kDrivePhases
                ? Printf("; the likelier valley, %.4f ms, brackets the final fit",
                         e.delta_t_s * 1e3)
                : std::string());
  return Printf(
      "drive phases: dt = %.4f ms +- %.4f ms (the fast drive's valley nearest the slow drive's "
      "%.3f +- %.3f ms, the next %.0f variances less likely; Hall axes agree %.3f / %.3f)%s",
      e.delta_t_s * 1e3, e.sigma_s * 1e3, e.slow.delta_t_s * 1e3, e.slow.sigma_s * 1e3,
      e.separation, e.fast.coherence, e.slow.coherence, brackets);
}

HallCalibrationStepResult RunHallCalibration(const fs::path& dir,
                                             const hall::HallCalibrationOptions& options) {
  HallCalibrationStepResult r;
  try {
    const auto t0 = std::chrono::steady_clock::now();
    const dataset::Recording rec = interchange::ReadRecording(dir);
    const fs::path planes_csv = dir / "results" / "mirror_planes.csv";
    if (!fs::exists(planes_csv))
      throw std::runtime_error(planes_csv.string() + ": not found; run `msmcal solve " +
                               dir.string() + "` first");
    const auto planes = ReadMirrorPlanesCsv(planes_csv);
    const HallCalibrationSetup setup = MakeHallCalibrationSetup(rec, planes, dir.string());
    const hall::HallCalibrationResult result = hall::CalibrateHall(setup.Input(), options);
    const double seconds = SecondsSince(t0);
    r.model_file = dir / "results" / "hall_model.yaml";
    interchange::WriteFileAtomically(r.model_file, FormatHallModelYaml(result, options));
    WriteHallSummary(dir / "results" / "summary.json", result, setup.poses.size());
    r.model = result.final_fit.model.kind;
    r.delta_t_s = result.final_fit.model.delta_t_s;
    r.time_offset = result.delta_t;
    const hall::TimeBase& tb = result.actual_time_base;
    r.text =
        FormatTableTwo(result, options) +
        Printf(
            "clock: actual %d edges (%d missing, %d rejected), rate error %.2f ppm, "
            "jitter %.2f us\n",
            tb.edges_used, tb.edges_missing, tb.edges_rejected, tb.RateErrorPpm(),
            tb.jitter_rms_us) +
        ActualPeriodsLine(result.actual_periods, setup.actual.readings.size()) +
        FormatDrivePhase(result.drive_phase, result.bracket) + "\n" +
        Printf(
            "model: %s, %s, wrote %s (%.1f s)\n", hall::ToString(r.model),
            FormatDeltaT(r.time_offset, r.model, r.delta_t_s, result.sine_in_field_valley).c_str(),
            r.model_file.string().c_str(), seconds);
    if (!r.time_offset.identified())
      r.log.push_back(
          {StepLogLine::Level::kWarning, "delta_t not identified (" +
                                             std::string(hall::ToString(r.time_offset.status)) +
                                             "): " + r.time_offset.reason});
  } catch (const std::exception& e) {
    r.error = e.what();
  }
  return r;
}

HallPredictionStepResult RunHallPrediction(const fs::path& model_file, const fs::path& readings_csv,
                                           const fs::path& poses_csv, const fs::path& clock_csv) {
  HallPredictionStepResult r;
  try {
    const HallModelFile loaded = ReadHallModelYaml(model_file);
    const auto readings = interchange::ReadHallReadingsCsv(readings_csv);
    hall::TimeBase tb = loaded.time_base;
    fs::path clock = clock_csv;
    if (clock.empty()) {
      const fs::path sibling =
          readings_csv.parent_path() / (readings_csv.stem().string() + "_clock.csv");
      if (fs::exists(sibling)) clock = sibling;
    }
    if (!clock.empty()) {
      const dataset::HallRecording rec = interchange::ReadHallCsv(readings_csv, clock);
      tb = hall::FitTimeBase(rec.clock_edges_us, loaded.time_base.pattern_period_s);
      r.log.push_back(
          {StepLogLine::Level::kInfo, Printf("time base from %s: rate error %.2f ppm",
                                             clock.string().c_str(), tb.RateErrorPpm())});
    } else {
      r.log.push_back(
          {StepLogLine::Level::kWarning, "no clock file for " + readings_csv.string() +
                                             ": using the calibration session's time base"});
    }
    const hall::HallPredictor predictor(loaded.model, loaded.background, loaded.actual_mean_uT);
    std::vector<double> t(readings.size());
    std::vector<Eigen::Vector3d> raw(readings.size()), pose(readings.size());
    for (size_t i = 0; i < readings.size(); ++i) {
      t[i] = tb.GeneratorTime(readings[i].mcu_time_us);
      raw[i] = Eigen::Vector3d(readings[i].bx_uT, readings[i].by_uT, readings[i].bz_uT);
    }
    const auto t0 = std::chrono::steady_clock::now();
    predictor.PredictBatch(t.data(), raw.data(), pose.data(), t.size());
    const double secs = SecondsSince(t0);
    std::vector<HallPoseRow> rows(t.size());
    const double dt = loaded.model.delta_t_s;
    for (size_t i = 0; i < t.size(); ++i)
      rows[i] = {readings[i].mcu_time_us, t[i] - dt, pose[i].x(), pose[i].y(), pose[i].z()};
    WriteHallPosesCsv(poses_csv, rows);
    r.poses = rows.size();
    r.text = Printf("predicted %zu poses (%.1f M readings/s) into %s\n", t.size(),
                    secs > 0 ? t.size() / secs / 1e6 : 0.0, poses_csv.c_str());
  } catch (const std::exception& e) {
    r.error = e.what();
  }
  return r;
}

}  // namespace msmcal::results
