// `msmcal solve DIR`: mirror poses from an interchange folder (MSM paper Sec. V-A), written to
// DIR/results/ (mirror_planes.csv, beams.csv, validation.csv, summary.json "mirror_poses", and the
// native validation_detail.csv). `msmcal experiment table1`: the paper's Table I on the simulated
// rig (3 spanning angles x 2 scan patterns, baseline vs proposed).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <sstream>

#include "app/command_registry.h"
#include "app/step_output.h"
#include "common/progress_line.h"
#include "common/units.h"
#include "mocks/rig/rig_simulator.h"
#include "processing/solver/diagnostics.h"
#include "processing/solver/home_frame.h"
#include "processing/solver/pipeline.h"
#include "processing/solver/stages/exposures.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/results/finish_steps.h"
#include "sessions/results/solve_options_io.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;

struct SolveArgs {
  std::string dir;
  std::string explain;  // one image file as named in session.yaml
  std::string config;   // solve.yaml
  int threads = 2;
  int ceres_threads = 1;
  uint64_t seed = 1;
  bool threads_given = false, seed_given = false;
};

// `msmcal solve DIR --explain FILE`: every board attempt and every candidate blob of one image,
// with the reason it was kept or refused.
void RunExplain(const SolveArgs& args, const solver::PipelineOptions& options) {
  const fs::path dir(args.dir);
  const dataset::Recording input = interchange::ReadRecordingForSolve(dir);
  // As the solve does (solver::CollapseExposures): the frame's repeated exposures are averaged
  // and measured as one scene, named by its first exposure.
  const solver::ExposureScenes exposures =
      options.average_exposures ? solver::CollapseExposures(input) : solver::ExposureScenes{};
  const dataset::Recording& rec = exposures.Collapsed() ? exposures.recording : input;
  const std::string explained = exposures.SceneOf(args.explain);
  const solver::ImageLoader read = [&](const std::string& file) {
    return cv::imread((dir / file).string(), cv::IMREAD_UNCHANGED);
  };
  const solver::ImageLoader load = [&](const std::string& file) {
    cv::Mat img = solver::LoadScene(exposures, read, file);
    if (img.empty()) throw std::runtime_error((dir / file).string() + ": cannot read the image");
    return img;
  };
  const vision::BoardSize world{rec.world_board.cols, rec.world_board.rows};
  const vision::BoardSize sliding{rec.sliding_board.cols, rec.sliding_board.rows};
  std::vector<vision::BoardSize> asks;
  std::vector<std::string> names;
  std::string what;
  int expected = 0;
  // The frame's static scene (the images its background is measured in): step 1 the same
  // sliding pose, step 2 every frame.
  std::vector<std::string> scene;
  std::vector<std::string> view_files;  // the frames of its view, in order (board hints)
  for (const auto& f : rec.step1)
    if (f.file == explained) {
      for (const auto& g : rec.step1)
        if (g.pose == f.pose && g.file != f.file) scene.push_back(g.file);
      expected = static_cast<int>(f.beams.size());
      asks = {world, sliding};
      names = {"world", "sliding"};
      for (const auto& g : rec.step1) view_files.push_back(g.file);
      what = "step 1, sliding pose " + std::to_string(f.pose) + ", " +
             std::to_string(f.beams.size()) + " beam(s) unblocked: expects " +
             std::to_string(f.beams.size()) + " dot(s) on the sliding plate";
    }
  for (const auto& f : rec.step2)
    if (f.file == explained) {
      for (const auto& g : rec.step2)
        if (g.file != f.file) scene.push_back(g.file);
      asks = {world};
      names = {"world"};
      for (const auto& g : rec.step2) view_files.push_back(g.file);
      const size_t triggers = f.kind == dataset::Step2Kind::kNeutral ? 1 : f.triggers.size();
      expected = static_cast<int>(triggers * f.beams.size());
      what = std::string("step 2, ") + dataset::ToString(f.kind) + ", " + std::to_string(triggers) +
             " trigger(s) x " + std::to_string(f.beams.size()) + " beam(s): expects " +
             std::to_string(triggers * f.beams.size()) + " dot(s) on the world plane";
    }
  if (asks.empty())
    throw std::runtime_error(args.explain + ": not a frame of " + (dir / "session.yaml").string() +
                             " (name it as session.yaml does, e.g. step1/0004.png)");
  const cv::Mat img = load(explained);
  double lo = 0, hi = 0;
  cv::minMaxLoc(img.reshape(1), &lo, &hi);
  if (const auto it = exposures.members.find(explained);
      it != exposures.members.end() && it->second.size() > 1) {
    std::string files;
    for (const auto& f : it->second) files += (files.empty() ? "" : ", ") + f;
    std::printf("%s: measured as the scene %s, the mean of %zu exposures (%s; average_exposures)\n",
                args.explain.c_str(), explained.c_str(), it->second.size(), files.c_str());
  }
  std::printf("%s: %dx%d, %d channel(s), %d-bit, levels %.0f..%.0f\n%s\n", explained.c_str(),
              img.cols, img.rows, img.channels(), img.depth() == CV_16U ? 16 : 8, lo, hi,
              what.c_str());
  if (img.channels() == 3) {
    const int parity = vision::InterpolatedGreenParity(img);
    if (parity < 0)
      std::printf("green channel: measured at every pixel (no Bayer interpolation seen)\n");
    else
      std::printf(
          "green channel: interpolated where (x + y) is %s (a Bayer sensor's demosaicing): dots "
          "are fitted to the measured half%s\n",
          parity == 0 ? "even" : "odd",
          options.dots.native_green_only ? "" : " only with dots.native_green_only (now off)");
  }
  // As the solve does (solver::ViewHints): boards searched first where the first frame of the
  // view that showed them had them; the view's earlier rounds are measured for that.
  std::optional<solver::ViewHints> view;
  if (options.hint_boards_from_first_frame) {
    const size_t position = static_cast<size_t>(
        std::find(view_files.begin(), view_files.end(), explained) - view_files.begin());
    view.emplace(asks.size(), view_files.size());
    for (;;) {
      const auto [begin, end] = view->NextRound();
      if (begin == end || position < end) break;
      std::vector<solver::ImageMeasurement> round;
      for (size_t k = begin; k < end; ++k)
        round.push_back(solver::MeasureImage(load(view_files[k]), asks, options.dots,
                                             options.boards, &view->hints()));
      for (size_t k = begin; k < end; ++k) view->Add(k, round[k - begin], options.boards);
    }
    std::printf(
        "board hints (boards.hint_from_first_frame: from the first frame of the view that "
        "found each board):\n");
    for (size_t b = 0; b < asks.size(); ++b) {
      if (const auto& h = view->hints()[b])
        std::printf("  %s: from %s, %s at scale %.3f in %dx%d+%d+%d\n", names[b].c_str(),
                    view_files[view->source(b)].c_str(), vision::ToString(h->method), h->scale,
                    h->region.width, h->region.height, h->region.x, h->region.y);
      else
        std::printf("  %s: none (no earlier round found it): the whole chain\n", names[b].c_str());
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  const solver::ImageMeasurement m =
      solver::MeasureFrame(img, asks, expected, options, view ? &view->hints() : nullptr);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("measured in %.2f s\n", secs);
  for (size_t b = 0; b < asks.size(); ++b) {
    std::printf("%s board (%dx%d inner corners): %s\n", names[b].c_str(), asks[b].cols,
                asks[b].rows,
                m.boards[b] ? (std::string("found by ") + vision::ToString(m.boards[b]->method) +
                               ", squares " + std::to_string(m.boards[b]->square_px).substr(0, 5) +
                               " px, " + std::to_string(m.boards[b]->corners_fitted) + " of " +
                               std::to_string(m.boards[b]->corners_px.size()) + " corners fitted")
                                  .c_str()
                            : "NOT FOUND");
    for (const auto& a : m.board_attempts[b])
      std::printf("  %-12s scale %.3f%s: %s%s%s (%.2f s)\n", vision::ToString(a.method), a.scale,
                  a.region.empty()
                      ? ""
                      : (" in " + std::to_string(a.region.width) + "x" +
                         std::to_string(a.region.height) + "+" + std::to_string(a.region.x) + "+" +
                         std::to_string(a.region.y) + (a.textured ? " (checker-like region)" : ""))
                            .c_str(),
                  !a.found     ? "no grid"
                  : a.accepted ? "accepted"
                               : "refused",
                  a.note.empty() ? "" : ": ", a.note.c_str(), a.seconds);
  }
  std::vector<vision::DotCandidate> cands;
  vision::DotRejections rej;
  vision::DetectDots(img, options.dots, &rej, &cands);
  std::printf(
      "dot candidates: %zu blobs above the threshold (dots.threshold_fraction %.3g), %zu "
      "kept\n",
      cands.size(), options.dots.threshold_fraction,
      static_cast<size_t>(
          std::count_if(cands.begin(), cands.end(), [](const auto& c) { return c.kept; })));
  // The blobs nearest the board that carries the dots first: those are the ones a reader looks
  // for (a frame has hundreds of board-residue blobs; only the first 60 are listed).
  const auto& host = asks.size() == 2 ? m.boards[1] : m.boards[0];
  if (host && !host->corners_px.empty()) {
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (const auto& p : host->corners_px) centre += p;
    centre /= static_cast<double>(host->corners_px.size());
    std::stable_sort(cands.begin(), cands.end(), [&](const auto& a, const auto& b) {
      if (a.kept != b.kept) return a.kept;
      return (a.centroid_px - centre).squaredNorm() < (b.centroid_px - centre).squaredNorm();
    });
  }
  size_t shown = 0;
  std::map<std::string, int> hidden;
  for (const auto& c : cands) {
    if (!c.kept && shown >= 60) {
      ++hidden[c.reason.substr(0, c.reason.find(':'))];
      continue;
    }
    ++shown;
    std::printf("  (%7.1f, %7.1f) %4d px peak %6.0f elong %.2f sat %3d: %s\n", c.centroid_px.x(),
                c.centroid_px.y(), c.num_pixels, c.peak, c.elongation, c.saturated_pixels,
                c.reason.c_str());
  }
  for (const auto& [why, n] : hidden)
    std::printf("  ... and %d more refused: %s\n", n, why.c_str());
  if (m.adaptive_dots) {
    std::printf(
        "the first pass fell short of the expected dots on the board's plane; the solve "
        "uses the second pass: %s\n",
        m.dot_settings.c_str());
  } else if (host && static_cast<int>(m.dots_on_plane) < expected && options.adaptive_dots) {
    std::printf(
        "the first pass fell short of the expected dots on the board's plane; a second "
        "pass with settings from the image's own noise and squares found %d there (kept "
        "only if more, and at most %d surplus):\n",
        m.second_pass_on_plane, options.max_surplus_dots);
  }
  if (host && static_cast<int>(m.dots_on_plane) < expected && options.adaptive_dots) {
    const vision::DotOptions adaptive =
        vision::AdaptiveDotOptions(img, host->square_px, options.dots);
    std::vector<vision::DotCandidate> c2;
    vision::DotRejections r2;
    vision::DetectDots(img, adaptive, &r2, &c2);
    int n = 0;
    for (const auto& c : c2)
      if (c.kept && n++ < 60)
        std::printf("  (%7.1f, %7.1f) %4d px peak %6.0f elong %.2f: %s\n", c.centroid_px.x(),
                    c.centroid_px.y(), c.num_pixels, c.peak, c.elongation, c.reason.c_str());
    std::printf("  (blobs fainter than %.2f of the brightest on the plane are then refused: %d)\n",
                options.adaptive_min_relative_peak, m.dot_rejections.too_faint);
  }
  std::printf(
      "on the board's plane (margins, roundness in the plane, square corners): %zu of %zu "
      "blobs\n",
      m.dots_on_plane, m.dots.size());
  if (host && options.dot_margin_from_data) {
    // The solve widens a step to the whole plane where that shows more of its frames their
    // dots (stages/measure.h, ResolveDotMargins): the frame's own count there.
    solver::RegionRejections region;
    const bool step1 = asks.size() == 2;
    solver::PipelineOptions whole_plane = options;
    whole_plane.step1_dot_margin_squares = whole_plane.step2_dot_margin_squares =
        std::numeric_limits<double>::infinity();
    const size_t whole = solver::DotsOnHostPlane(m.dots, m, asks, whole_plane, &region).size();
    std::printf(
        "on the board's whole plane (beyond %s = %g; the solve takes it for the step where more "
        "of its frames show their dots there, dot_margin_from_data): %zu of %zu blobs\n",
        step1 ? "step1_dot_margin_squares" : "step2_dot_margin_squares",
        step1 ? options.step1_dot_margin_squares : options.step2_dot_margin_squares, whole,
        m.dots.size());
  }
  // Shown whenever the frame has a static scene: which frames the solve measures this way
  // depends on the other frames too (stages/measure.cc, DotsOverStaticBackground).
  if (host && options.background_dots && !scene.empty()) {
    vision::StaticBackground background;
    background.Add(img);
    for (const auto& file : scene) {
      cv::Mat other;
      try {
        other = load(file);
      } catch (const std::exception&) {  // reported below, as a file left out
      }
      if (other.empty() || !background.Add(other))
        std::printf("  (%s cannot be read or differs in size: left out of the background)\n",
                    file.c_str());
    }
    std::vector<vision::DotCandidate> c3;
    vision::DotOptions opts;
    const std::vector<vision::Dot> dots3 = vision::DetectDotsOverBackgroundAdaptive(
        img, background.Without(img), host->square_px, options.dots, &opts, nullptr, &c3);
    std::printf(
        "a third pass on the frame's difference from its static scene (%zu other images; "
        "threshold %.3g of full scale; the solve uses it where the count above is off, or where "
        "a frame of the scene with every beam blocked shows blobs, and it comes closer; step 1 "
        "only if each beam is blocked in another image of the pose) keeps:\n",
        background.count() - 1, opts.threshold_fraction);
    int n = 0;
    for (const auto& c : c3)
      if (c.kept && n++ < 60)
        std::printf("  (%7.1f, %7.1f) %4d px peak %6.0f elong %.2f sat %3d: %s\n",
                    c.centroid_px.x(), c.centroid_px.y(), c.num_pixels, c.peak, c.elongation,
                    c.saturated_pixels, c.reason.c_str());
    // The same plane-level filters as the passes above: what the solve would count from it.
    const double margin =
        asks.size() == 2 ? options.step1_dot_margin_squares : options.step2_dot_margin_squares;
    solver::RegionRejections region;
    const size_t on_plane = solver::DotsOnHostPlane(dots3, m, asks, options, &region).size();
    std::printf(
        "  of these, on the board's plane (within %g squares): %zu of %zu (refused: %d off the "
        "plane, %d at a square corner, %d elongated in the plane)\n",
        margin, on_plane, dots3.size(), region.off_plane, region.junction,
        region.surface_elongated);
  }
}

solver::PipelineOptions OptionsOf(const SolveArgs& args) {
  solver::PipelineOptions options;
  if (!args.config.empty()) options = results::ReadSolveOptions(args.config, options);
  // The command line wins over the file for what it names.
  if (args.threads_given) options.image_threads = args.threads;
  options.mle.num_threads = args.ceres_threads;
  if (args.seed_given) options.seed = args.seed;
  if (const std::string e = options.Validate(); !e.empty())
    throw std::runtime_error("solve settings: " + e);
  return options;
}

void RunSolve(const SolveArgs& args) {
  // Settings first: a bad knob is reported before any file of the folder is read.
  const solver::PipelineOptions options = OptionsOf(args);
  std::unique_ptr<common::ProgressLine> progress;  // on a terminal only (stderr)
  std::mutex progress_mu;
  const results::SolveStepResult r =
      results::RunSolveStep(args.dir, options, [&](size_t read, size_t total) {
        std::lock_guard<std::mutex> lock(progress_mu);
        if (!progress) progress = std::make_unique<common::ProgressLine>("solve", total, "images");
        progress->Update(read, read < total ? "reading and measuring" : "estimating");
      });
  progress.reset();
  PrintStepReport(r);
  if (!r.ok()) throw std::runtime_error(r.error);
}

struct Table1Args {
  uint64_t seed = 1;
  std::string out;
  std::vector<int> rows;
  std::string config;  // solve.yaml for every row's solve (empty: the defaults)
};

struct Table1Row {
  std::string name;
  double spanning = 0;
  double base_rms = 0, base_sd = 0, prop_rms = 0, prop_sd = 0;
  double normal_rms_deg = 0;
  double trans_rms_mm = 0;
  double normalised = 0;
  std::string failed;  // the solver's error when the session could not be solved
  size_t dropped = 0;
};

void MeanSd(const std::vector<double>& v, double* rms, double* sd) {
  double s2 = 0, m = 0;
  for (double x : v) {
    s2 += x * x;
    m += x;
  }
  const double n = std::max<double>(1, v.size());
  m /= n;
  *rms = std::sqrt(s2 / n);
  double var = 0;
  for (double x : v) var += (x - m) * (x - m);
  *sd = std::sqrt(var / n);
}

void RunTable1(const Table1Args& args) {
  solver::PipelineOptions options;
  if (!args.config.empty()) options = results::ReadSolveOptions(args.config, options);
  if (const std::string e = options.Validate(); !e.empty())
    throw std::runtime_error("solve settings: " + e);
  const double spans[3] = {18.0, 27.0, 46.0};
  std::vector<Table1Row> table;
  size_t rows_to_run = 0;
  for (int index = 1; index <= 6; ++index)
    rows_to_run += args.rows.empty() ||
                   std::find(args.rows.begin(), args.rows.end(), index) != args.rows.end();
  common::ProgressLine progress("experiment table1", rows_to_run, "rows");
  for (int pattern = 0; pattern < 2; ++pattern) {
    for (int k = 0; k < 3; ++k) {
      const int index = pattern * 3 + k + 1;
      if (!args.rows.empty() &&
          std::find(args.rows.begin(), args.rows.end(), index) == args.rows.end())
        continue;
      sim::SimOptions o;
      o.seed = args.seed + index;
      o.beams.spanning_angle_deg = spans[k];
      if (pattern == 1) {  // Pattern B: other drive frequencies and amplitudes.
        o.mirror.fast.frequency_hz = 200.0;
        o.mirror.fast.amplitude_vpp = 2.5;
        o.mirror.slow.frequency_hz = 4.0;
        o.mirror.slow.amplitude_vpp = 3.5;
      }
      const sim::RigSimulator simulator(o);
      const dataset::Recording rec = simulator.MakeRecording(/*with_hall=*/false);
      const std::string row_name =
          std::string("Pattern-") + (pattern == 0 ? "A-" : "B-") + std::to_string(index);
      std::atomic<size_t> images{0};
      const solver::ImageLoader load = [&](const std::string& file) -> cv::Mat {
        progress.Update(table.size(), row_name + ": " + std::to_string(++images) + " images read");
        for (size_t i = 0; i < rec.step1.size(); ++i)
          if (rec.step1[i].file == file) return simulator.RenderStep1Frame(i);
        for (size_t i = 0; i < rec.step2.size(); ++i)
          if (rec.step2[i].file == file) return simulator.RenderStep2Frame(i);
        return cv::Mat();
      };
      Table1Row row;
      row.name = std::string("Pattern-") + (pattern == 0 ? "A-" : "B-") + std::to_string(index);
      solver::SolveOutput out;
      try {
        out = solver::SolveRecording(rec, load, options);
      } catch (const solver::SolveError& e) {
        // One unsolvable session must not lose the other rows: report it in the table.
        std::printf("%s failed: %s\n", row.name.c_str(), e.what());
        row.failed = e.what();
        table.push_back(row);
        progress.Update(table.size(), row.name + " failed");
        continue;
      }
      row.spanning = out.mean_spanning_angle_deg;
      std::vector<double> b, p;
      for (const auto& v : out.validation) {
        b.push_back(v.baseline.err_deg);
        p.push_back(v.row.err_deg);
      }
      MeanSd(b, &row.base_rms, &row.base_sd);
      MeanSd(p, &row.prop_rms, &row.prop_sd);
      double s2 = 0;
      for (const auto& pl : out.planes) {
        const geometry::Plane truth =
            simulator.MirrorPlaneInWorld(simulator.triggers()[pl.j].t_s, sim::DriveMode::kScan);
        const double e = common::RadToDeg(geometry::AngleBetween(pl.plane_in_world.n, truth.n));
        s2 += e * e;
      }
      row.normal_rms_deg = std::sqrt(s2 / std::max<double>(1, out.planes.size()));
      {
        // Poses vs truth in the solver's {0} convention (processing/solver/home_frame.h).
        std::vector<geometry::Plane> true_scan;
        for (const auto& pl : out.planes)
          true_scan.push_back(
              simulator.MirrorPlaneInWorld(simulator.triggers()[pl.j].t_s, sim::DriveMode::kScan));
        const geometry::Rigid3d tf =
            solver::ConventionalTruthFrame(simulator.world_from_mirror0(), true_scan);
        double t2 = 0;
        for (size_t k = 0; k < out.planes.size(); ++k)
          t2 += std::pow(
              out.planes[k].trans_mm - geometry::PoseFromWorldPlane(tf, true_scan[k]).trans_mm, 2);
        row.trans_rms_mm = std::sqrt(t2 / std::max<double>(1, out.planes.size()));
      }
      row.normalised = out.rms_normalised_validation;
      row.dropped = out.dropped.size();
      std::printf("%s done: spanning %.2f, baseline %.3f, proposed %.3f deg\n", row.name.c_str(),
                  row.spanning, row.base_rms, row.prop_rms);
      for (const auto& d : out.dropped)
        std::printf("  %s dropped %s: %s\n", row.name.c_str(), d.file.c_str(), d.reason.c_str());
      std::fflush(stdout);
      table.push_back(row);
      progress.Update(table.size(), row.name + " done");
    }
  }
  progress.Finish();
  std::ostringstream s;
  s << "| Dataset | Avg. spanning angle (deg) | Baseline error (deg) | Proposed error (deg) | "
       "Plane normal RMS vs truth (deg) | Trans RMS vs truth (mm) | Normalised validation RMS | "
       "Dropped frames |\n"
       "|---|---|---|---|---|---|---|---|\n";
  char buf[512];
  for (const auto& r : table) {
    if (!r.failed.empty()) {
      s << "| " << r.name << " | solve failed: " << r.failed.substr(0, 120) << " | | | | | | |\n";
      continue;
    }
    std::snprintf(buf, sizeof(buf),
                  "| %s | %.2f | %.3f ± %.3f | %.3f ± %.3f | %.4f | %.4f | %.2f | %zu |\n",
                  r.name.c_str(), r.spanning, r.base_rms, r.base_sd, r.prop_rms, r.prop_sd,
                  r.normal_rms_deg, r.trans_rms_mm, r.normalised, r.dropped);
    s << buf;
  }
  std::printf("%s", s.str().c_str());
  if (!args.out.empty()) interchange::WriteFileAtomically(args.out, s.str());
}

void AddSolveCommands(CLI::App& app) {
  auto solve_args = std::make_shared<SolveArgs>();
  auto* solve = app.add_subcommand("solve", "Estimate mirror poses from an interchange folder");
  solve->add_option("DIR", solve_args->dir, "Interchange folder (results/ is written there)")
      ->required();
  solve
      ->add_option("--threads", solve_args->threads,
                   "Images measured in parallel (the results do not depend on it)")
      ->check(CLI::PositiveNumber);
  solve
      ->add_option("--ceres-threads", solve_args->ceres_threads,
                   "Ceres threads (> 1 is faster on large problems, but then the last digits of "
                   "the results vary from run to run)")
      ->check(CLI::PositiveNumber);
  solve->add_option("--seed", solve_args->seed, "Seed of the trigger-assignment RANSAC");
  solve->add_option("--explain", solve_args->explain,
                    "Explain one image (as named in session.yaml, e.g. step1/0004.png): every "
                    "board attempt and candidate blob with the reason it was kept or refused; "
                    "solves nothing");
  solve->add_option("--config", solve_args->config,
                    "Solver settings (YAML: every detection and gating knob; the values used are "
                    "written to DIR/results/solve_options.yaml, which this option reads back)");
  solve->callback([solve_args, solve]() {
    solve_args->threads_given = solve->count("--threads") > 0;
    solve_args->seed_given = solve->count("--seed") > 0;
    if (!solve_args->explain.empty())
      RunExplain(*solve_args, OptionsOf(*solve_args));
    else
      RunSolve(*solve_args);
  });

  auto t1 = std::make_shared<Table1Args>();
  CLI::App* exp =
      GetOrAddSubcommand(app, "experiment", "Reproduce the papers' tables on simulated data");
  auto* table1 = exp->add_subcommand(
      "table1", "MSM paper Table I: baseline vs proposed on 3 spanning angles x 2 patterns");
  table1->add_option("--seed", t1->seed, "Base seed of the simulated sessions");
  table1->add_option("--out", t1->out, "Also write the Markdown table to this file");
  table1->add_option("--rows", t1->rows, "Only these rows (1..6)")->check(CLI::Range(1, 6));
  table1
      ->add_option("--config", t1->config,
                   "Solver settings for every row (solve.yaml, as msmcal solve --config)")
      ->check(CLI::ExistingFile);
  table1->callback([t1]() { RunTable1(*t1); });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/40, AddSolveCommands);

}  // namespace msmcal::app
