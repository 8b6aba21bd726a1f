#include "sessions/results/solve_options_io.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <variant>
#include <vector>

#include "common/file_text.h"
#include "common/text_io.h"
#include "common/yaml_fields.h"

namespace msmcal::results {
namespace {

using Ref = std::variant<double*, int*, bool*, uint64_t*, vision::DotCentre*>;

struct Knob {
  std::string key;  // "dots.min_pixels"
  Ref ref;
  std::string help;
};

// The one table of knobs: reading and writing both walk it.
std::vector<Knob> Knobs(solver::PipelineOptions& o) {
  return {
      {"image_threads", &o.image_threads,
       "images measured in parallel (results do not depend on it)"},
      {"average_exposures", &o.average_exposures,
       "average repeated exposures of one static scene before measuring"},
      {"seed", &o.seed, "seed of the trigger-assignment RANSAC"},
      {"dots.threshold_fraction", &o.dots.threshold_fraction,
       "spot signal threshold, fraction of full scale (after the top-hat)"},
      {"dots.min_pixels", &o.dots.min_pixels, "smallest blob (pixels above threshold) kept"},
      {"dots.max_pixels", &o.dots.max_pixels, "largest blob kept"},
      {"dots.max_elongation", &o.dots.max_elongation,
       "largest ratio of a blob's principal std devs in the image"},
      {"dots.max_saturated_fraction", &o.dots.max_saturated_fraction,
       "largest fraction of a blob's pixels at full scale"},
      {"dots.plateau_tolerance_fraction", &o.dots.plateau_tolerance_fraction,
       "largest depth (fraction of its maximum) of a flat top's dips taken as clipped"},
      {"dots.background_kernel_px", &o.dots.background_kernel_px,
       "top-hat kernel (odd px; larger than a spot, smaller than a square; 0: raw signal)"},
      {"dots.min_green_excess_fraction", &o.dots.min_green_excess_fraction,
       "BGR: least green - max(blue, red) of a laser blob, fraction of full scale"},
      {"dots.centre", &o.dots.centre, "gaussian_fit or weighted_centroid"},
      {"dots.fit_margin_px", &o.dots.fit_margin_px, "Gaussian fit window: blob box grown by this"},
      {"dots.native_green_only", &o.dots.native_green_only,
       "BGR from a Bayer sensor: fit spots to the measured greens only (detected per image)"},
      {"dots.max_fit_shift_px", &o.dots.max_fit_shift_px,
       "a fit moving the centre further than this keeps the centroid"},
      {"dots.background_mask_margin_px", &o.dots.background_mask_margin_px,
       "other images' dots masked with their box grown by this (background refit)"},
      {"boards.coarse_max_side_px", &o.boards.coarse_max_side_px,
       "coarse board search on an image of at most this longer side"},
      {"boards.try_sb_full", &o.boards.try_sb_full,
       "fallback: findChessboardCornersSB at full resolution"},
      {"boards.try_classic", &o.boards.try_classic,
       "fallback: classic findChessboardCorners (adaptive threshold) + cornerSubPix"},
      {"boards.classic_max_corners", &o.boards.classic_max_corners,
       "the classic fallback only for boards of at most this many inner corners"},
      {"boards.try_sb_upscaled", &o.boards.try_sb_upscaled, "fallback: SB on a 2x upscaled copy"},
      {"boards.upscale_max_side_px", &o.boards.upscale_max_side_px,
       "the upscaled fallback only where the upscaled longer side stays below this"},
      {"boards.textured_regions", &o.boards.textured_regions,
       "where SB misses on the whole image: the detectors on this many checker-like regions (0: "
       "off)"},
      {"boards.max_refine_shift_squares", &o.boards.max_refine_shift_squares,
       "refuse a grid whose sub-pixel refinement moves a corner more than this (squares)"},
      {"boards.refine_window_squares", &o.boards.refine_window_squares,
       "cornerSubPix half window, as a fraction of the smallest corner spacing"},
      {"boards.refine_window_min_px", &o.boards.refine_window_min_px,
       "cornerSubPix half window at least this (px), at most half the corner spacing"},
      {"boards.fit_corners", &o.boards.fit_corners,
       "refine each corner by fitting a blurred-corner model to the same window"},
      {"boards.fit_max_radius_px", &o.boards.fit_max_radius_px,
       "the corner model fit reads the refinement window, at most this radius (px)"},
      {"boards.min_contrast_levels", &o.boards.min_contrast_levels,
       "no board search on an image whose grey levels span less (8-bit, 0.1-99.9 %; 0: off)"},
      {"boards.hint_from_first_frame", &o.hint_boards_from_first_frame,
       "search a view's boards first where its first frame showed them, with that detector"},
      {"boards.hint_margin_squares", &o.boards.hint_margin_squares,
       "that search region: the first frame's board grown by this many squares"},
      {"boards.max_grid_irregularity_squares", &o.boards.max_grid_irregularity_squares,
       "refuse a grid with a corner this far off its neighbours' line (squares)"},
      {"step1_dot_margin_squares", &o.step1_dot_margin_squares,
       "step 1 dots: on the sliding plate within this many squares of its pattern"},
      {"step2_dot_margin_squares", &o.step2_dot_margin_squares,
       "step 2 dots: on the world plane within this many squares of its pattern"},
      {"dot_margin_from_data", &o.dot_margin_from_data,
       "a step whose listed dots lie beyond its margin in more frames takes the whole plane"},
      {"max_surface_elongation", &o.max_surface_elongation,
       "largest elongation of a spot in the board's own plane"},
      {"junction_elongation", &o.junction_elongation,
       "blobs more elongated than this at a square corner are board residue"},
      {"junction_exclusion_squares", &o.junction_exclusion_squares,
       "radius around inner corners for that test (squares)"},
      {"adaptive_dots", &o.adaptive_dots,
       "measure a frame short of dots again with settings from its own noise and squares"},
      {"adaptive_min_relative_peak", &o.adaptive_min_relative_peak,
       "in that pass, refuse blobs fainter than this fraction of the frame's brightest"},
      {"background_dots", &o.background_dots,
       "measure a frame still short of dots on its difference from its static scene"},
      {"static_blob_radius_px", &o.static_blob_radius_px,
       "drop blobs at one place in frames whose light differs (scene structure); 0: off"},
      {"max_surplus_dots", &o.max_surplus_dots,
       "step 2: extra blobs a frame may have and still be grouped"},
      {"max_group_residual_px", &o.max_group_residual_px,
       "worst mean pixel inconsistency of one mirror plane's dots"},
      {"partial_frame_group_residual_px", &o.partial_frame_group_residual_px,
       "the same for a frame with dots missing"},
      {"ransac_iterations", &o.ransac_iterations, "trigger assignment: RANSAC iterations"},
      {"ransac_inlier_deg", &o.ransac_inlier_deg, "trigger assignment: inlier threshold, deg"},
      {"mle.max_iterations", &o.mle.max_iterations, "Ceres iterations"},
      {"mle.estimate_variance_factors", &o.mle.estimate_variance_factors,
       "rescale each residual family's covariance by its posterior variance factor"},
      {"mle.variance_passes", &o.mle.variance_passes, "passes of that estimation"},
  };
}

// "<path>:<line>: <key>: <what>" (common/yaml_fields.h).
[[noreturn]] void Fail(const std::string& path, const YAML::Node& n, const std::string& key,
                       const std::string& what) {
  common::YamlFields(path).Fail(n, key, what);
}

void Assign(const std::string& path, const YAML::Node& n, const Knob& k) {
  if (!n.IsScalar()) Fail(path, n, k.key, "expected a scalar");
  const std::string text = n.Scalar();
  std::visit(
      [&](auto* p) {
        using T = std::remove_pointer_t<decltype(p)>;
        if constexpr (std::is_same_v<T, bool>) {
          if (text == "true")
            *p = true;
          else if (text == "false")
            *p = false;
          else
            Fail(path, n, k.key, "expected true or false, got '" + text + "'");
        } else if constexpr (std::is_same_v<T, vision::DotCentre>) {
          if (text == "gaussian_fit")
            *p = vision::DotCentre::kGaussianFit;
          else if (text == "weighted_centroid")
            *p = vision::DotCentre::kWeightedCentroid;
          else
            Fail(path, n, k.key, "expected gaussian_fit or weighted_centroid, got '" + text + "'");
        } else {
          size_t used = 0;
          double v = 0;
          try {
            v = std::stod(text, &used);
          } catch (const std::exception&) {
            used = 0;
          }
          if (used != text.size() || !std::isfinite(v))
            Fail(path, n, k.key, "expected a finite number, got '" + text + "'");
          if constexpr (std::is_same_v<T, double>) {
            *p = v;
          } else {
            if (v != std::floor(v) || std::abs(v) > 9e15)
              Fail(path, n, k.key, "expected an integer, got '" + text + "'");
            if constexpr (std::is_same_v<T, uint64_t>) {
              if (v < 0)
                Fail(path, n, k.key, "expected a non-negative integer, got '" + text + "'");
            } else {
              if (std::abs(v) > 2e9) Fail(path, n, k.key, "integer out of range: '" + text + "'");
            }
            *p = static_cast<T>(v);
          }
        }
      },
      k.ref);
}

void Walk(const std::string& path, const YAML::Node& node, const std::string& prefix,
          const std::vector<Knob>& knobs, std::set<std::string>* seen) {
  if (!node.IsMap()) Fail(path, node, prefix.empty() ? "(top level)" : prefix, "expected a map");
  for (const auto& kv : node) {
    const std::string key =
        prefix + common::YamlFields(path).KeyAt(kv.first, prefix.empty() ? "(top level)" : prefix);
    if (kv.second.IsMap()) {
      Walk(path, kv.second, key + ".", knobs, seen);
      continue;
    }
    const auto it =
        std::find_if(knobs.begin(), knobs.end(), [&](const Knob& k) { return k.key == key; });
    if (it == knobs.end()) {
      std::string known;
      for (const auto& k : knobs) known += (known.empty() ? "" : ", ") + k.key;
      Fail(path, kv.first, key, "unknown setting (known: " + known + ")");
    }
    Assign(path, kv.second, *it);
    seen->insert(key);
  }
}

}  // namespace

solver::PipelineOptions ReadSolveOptions(const std::string& path,
                                         const solver::PipelineOptions& defaults) {
  solver::PipelineOptions o = defaults;
  const YAML::Node root =
      common::YamlFields(path).Load(common::ReadFileText(path, "cannot read the file"));
  std::set<std::string> seen;
  if (!root.IsNull()) Walk(path, root, "", Knobs(o), &seen);
  if (const std::string e = o.Validate(); !e.empty())
    throw std::runtime_error(path + ": invalid setting: " + e);
  return o;
}

std::string FormatSolveOptions(const solver::PipelineOptions& options) {
  solver::PipelineOptions o = options;
  std::ostringstream s;
  s << "# msmcal solve settings (msmcal solve DIR --config THIS_FILE repeats the run)\n";
  std::string group;
  for (const Knob& k : Knobs(o)) {
    const size_t dot = k.key.find('.');
    const std::string g = dot == std::string::npos ? "" : k.key.substr(0, dot);
    const std::string name = dot == std::string::npos ? k.key : k.key.substr(dot + 1);
    if (g != group) {
      if (!g.empty()) s << g << ":\n";
      group = g;
    }
    s << (g.empty() ? "" : "  ") << name << ": ";
    std::visit(
        [&](auto* p) {
          using T = std::remove_pointer_t<decltype(p)>;
          if constexpr (std::is_same_v<T, bool>)
            s << (*p ? "true" : "false");
          else if constexpr (std::is_same_v<T, vision::DotCentre>)
            s << (*p == vision::DotCentre::kGaussianFit ? "gaussian_fit" : "weighted_centroid");
          else if constexpr (std::is_same_v<T, double>)
            s << common::YamlDouble(*p);
          else
            s << *p;
        },
        k.ref);
    s << "  # " << k.help << "\n";
  }
  return s.str();
}

}  // namespace msmcal::results
