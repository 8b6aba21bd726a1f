#include "processing/solver/diagnostics.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <map>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "common/number_format.h"
#include "processing/vision/checkerboard.h"

namespace msmcal::solver {
namespace {

std::string CleanText(std::string s) {
  for (char& c : s)
    if (c == ',' || c == '\n' || c == '\r' || c == '"') c = c == ',' ? ';' : ' ';
  return s;
}

std::string Num(double v, int decimals = 3) {
  if (v < 0) return "";
  return common::FormatFixed(v, decimals);
}

// A reason with its numbers replaced by N, so that frames with the same problem count as one.
std::string Pattern(const std::string& reason) {
  std::string out;
  bool in_number = false;
  for (size_t i = 0; i < reason.size(); ++i) {
    const char c = reason[i];
    const bool digit = std::isdigit(static_cast<unsigned char>(c)) ||
                       (in_number && (c == '.' || c == 'e' || c == '-'));
    if (digit) {
      if (!in_number) out += 'N';
      in_number = true;
    } else {
      in_number = false;
      out += c;
    }
  }
  return out;
}

}  // namespace

std::vector<std::string> DetectionsCsvColumns() {
  return {"file",
          "step",
          "used",
          "reason",
          "scene",
          "partial",
          "note",
          "world_found",
          "world_method",
          "world_square_px",
          "world_corner_rms_px",
          "sliding_found",
          "sliding_method",
          "sliding_square_px",
          "sliding_corner_rms_px",
          "blobs",
          "dots_found",
          "dots_expected",
          "rejected_too_small",
          "rejected_too_large",
          "rejected_elongated",
          "rejected_saturated",
          "rejected_not_green",
          "rejected_too_faint",
          "rejected_off_plane",
          "rejected_at_corner",
          "rejected_surface_elongated",
          "fit_fallbacks",
          "rejected_static"};
}

std::string FormatDetectionsCsv(const std::vector<FrameDetection>& detections) {
  std::ostringstream s;
  const auto cols = DetectionsCsvColumns();
  for (size_t i = 0; i < cols.size(); ++i) s << (i ? "," : "") << cols[i];
  s << '\n';
  for (const auto& d : detections) {
    s << CleanText(d.file) << ',' << d.step << ',' << (d.used ? 1 : 0) << ',' << CleanText(d.reason)
      << ',' << CleanText(d.scene) << ',' << (d.partial ? 1 : 0) << ',' << CleanText(d.note);
    for (const char* name : {"world", "sliding"}) {
      const auto it = std::find_if(d.boards.begin(), d.boards.end(),
                                   [&](const FrameDetection::Board& b) { return b.name == name; });
      if (it == d.boards.end()) {
        s << ",,,,";
        continue;
      }
      s << ',' << (it->found ? 1 : 0) << ',' << it->method << ','
        << (it->found ? Num(it->square_px, 2) : "") << ','
        << (it->found ? Num(it->corner_rms_px, 4) : "");
    }
    s << ',' << d.blobs << ',' << (d.dots_found >= 0 ? std::to_string(d.dots_found) : "") << ','
      << d.dots_expected << ',' << d.rejected.too_small << ',' << d.rejected.too_large << ','
      << d.rejected.elongated << ',' << d.rejected.saturated << ',' << d.rejected.not_green << ','
      << d.rejected.too_faint << ',' << d.off_plane << ',' << d.junction << ','
      << d.surface_elongated << ',' << d.rejected.fit_fallbacks << ',' << d.rejected.static_blob
      << '\n';
  }
  return s.str();
}

cv::Mat AnnotateFrame(const cv::Mat& image, const FrameDetection& d) {
  cv::Mat out = vision::ToBgr8(image, "AnnotateFrame");
  const double scale = std::max(1.0, std::max(out.cols, out.rows) / 1600.0);
  const int thick = std::max(1, static_cast<int>(std::lround(scale)));
  auto pt = [](const Eigen::Vector2d& p) {
    return cv::Point(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
  };
  for (const auto& b : d.boards) {
    if (!b.found || b.corners_px.empty()) continue;
    const cv::Scalar colour = b.name == "world" ? cv::Scalar(255, 160, 0) : cv::Scalar(255, 0, 255);
    for (const auto& c : b.corners_px) cv::circle(out, pt(c), 2 * thick, colour, thick);
    cv::circle(out, pt(b.corners_px.front()), 8 * thick, colour, 2 * thick);
    cv::putText(out, b.name + " (" + b.method + ")", pt(b.corners_px.front()) + cv::Point(10, -10),
                cv::FONT_HERSHEY_SIMPLEX, 0.5 * scale, colour, thick);
  }
  for (size_t i = 0; i < d.dots_px.size(); ++i) {
    cv::circle(out, pt(d.dots_px[i]), 9 * thick, cv::Scalar(0, 255, 0), thick);
    cv::putText(out, std::to_string(i), pt(d.dots_px[i]) + cv::Point(11, 4),
                cv::FONT_HERSHEY_SIMPLEX, 0.45 * scale, cv::Scalar(0, 255, 0), thick);
  }
  for (const auto& r : d.refused_px) {
    const cv::Point c = pt(r);
    const int k = 6 * thick;
    cv::line(out, c - cv::Point(k, k), c + cv::Point(k, k), cv::Scalar(0, 140, 255), thick);
    cv::line(out, c - cv::Point(-k, k), c + cv::Point(-k, k), cv::Scalar(0, 140, 255), thick);
  }
  const std::string verdict = !d.used ? "DROPPED: " + d.reason : "USED IN PART: " + d.note;
  const std::string counts = "dots on the plane " +
                             (d.dots_found >= 0 ? std::to_string(d.dots_found) : "-") + " of " +
                             std::to_string(d.dots_expected) + " expected; " +
                             std::to_string(d.blobs) + " blobs passed the image checks";
  const int banner = static_cast<int>(60 * scale);
  cv::rectangle(out, cv::Rect(0, 0, out.cols, banner), cv::Scalar(0, 0, 0), cv::FILLED);
  cv::putText(out, d.file + "  " + verdict.substr(0, 150),
              cv::Point(8, static_cast<int>(22 * scale)), cv::FONT_HERSHEY_SIMPLEX, 0.55 * scale,
              cv::Scalar(0, 0, 255), thick);
  cv::putText(out, counts, cv::Point(8, static_cast<int>(48 * scale)), cv::FONT_HERSHEY_SIMPLEX,
              0.5 * scale, cv::Scalar(255, 255, 255), thick);
  return out;
}

DropSummary SummariseDrops(const std::vector<FrameDetection>& detections) {
  DropSummary s;
  std::map<std::string, int> count;
  std::map<std::string, std::vector<const FrameDetection*>> frames_of;
  for (const auto& d : detections) {
    ++s.frames;
    if (d.partial) ++s.partial;
    if (d.used) continue;
    ++s.dropped;
    const std::string p = Pattern(d.reason);
    ++count[p];
    frames_of[p].push_back(&d);
  }
  if (s.dropped == 0) return s;
  for (const auto& [p, n] : count)
    if (n > s.common_count) {
      s.common_count = n;
      s.common_reason = p;
    }
  const auto& frames = frames_of[s.common_reason];
  const int n = static_cast<int>(frames.size());
  auto of = [&](int k) { return std::to_string(k) + " of " + std::to_string(n) + " frames"; };
  const std::string& r = s.common_reason;
  if (r.find("board") != std::string::npos && r.find("not found") != std::string::npos) {
    s.hint = "the board was not found in " + of(n) +
             ": check that it is whole in view, in focus and evenly lit, and that "
             "session.yaml's inner_corners match it; `msmcal solve DIR --explain FILE` shows "
             "every detector's attempt";
  } else if (r.find("laser dots") != std::string::npos) {
    // Which refusal dominates in these frames.
    int small = 0, large = 0, elong = 0, sat = 0, green = 0, off = 0, corner = 0, surf = 0,
        none = 0;
    for (const auto* d : frames) {
      if (d->dots_found >= d->dots_expected) continue;
      const int counts[] = {d->rejected.too_small, d->rejected.too_large, d->rejected.elongated,
                            d->rejected.saturated, d->rejected.not_green, d->off_plane,
                            d->junction,           d->surface_elongated};
      // Blobs refused on the plane (off it, at a corner, elongated there) passed every image
      // test: they are the spots a frame is short of, where there are any; the image tests'
      // counts are mostly board residue.
      const int* first = std::begin(counts);
      if (d->off_plane + d->junction + d->surface_elongated > 0) first = std::begin(counts) + 5;
      const int best =
          static_cast<int>(std::max_element(first, std::end(counts)) - std::begin(counts));
      if (counts[best] == 0) {
        ++none;
        continue;
      }
      int* slots[] = {&small, &large, &elong, &sat, &green, &off, &corner, &surf};
      ++*slots[best];
    }
    const std::pair<int, std::string> hints[] = {
        {small, "spots smaller than dots.min_pixels in " + of(small) +
                    ": lower it in solve.yaml or check focus"},
        {large, "blobs larger than dots.max_pixels in " + of(large) +
                    ": raise it in solve.yaml (defocused spots) or lower the laser power"},
        {elong, "blobs more elongated than dots.max_elongation in " + of(elong) +
                    ": raise it in solve.yaml (oblique views) or check focus"},
        {sat, "saturated blobs refused in " + of(sat) + ": raise dots.max_saturated_fraction"},
        {green, "blobs not green enough in " + of(green) +
                    ": lower dots.min_green_excess_fraction or check the colour balance"},
        {off, "blobs off the board's plane in " + of(off) +
                  ": raise step1_dot_margin_squares / step2_dot_margin_squares in solve.yaml"},
        {corner, "blobs at square corners refused in " + of(corner) +
                     ": lower junction_exclusion_squares in solve.yaml"},
        {surf, "blobs elongated in the board's plane in " + of(surf) +
                   ": raise max_surface_elongation in solve.yaml (grazing incidence)"},
        {none, "no blob above the threshold in " + of(none) +
                   ": lower dots.threshold_fraction in solve.yaml, raise the laser power or the "
                   "exposure"}};
    const auto best =
        std::max_element(std::begin(hints), std::end(hints),
                         [](const auto& a, const auto& b) { return a.first < b.first; });
    s.hint = best->first > 0
                 ? best->second
                 : "dots found but not the number expected (two spots merged, or a stray "
                   "light): check the frame's beams and triggers in session.yaml";
  } else if (r.find("group") != std::string::npos) {
    s.hint = "reflected dots that do not fit one mirror plane in " + of(n) +
             ": check the frames' beams and triggers in session.yaml, or raise "
             "max_group_residual_px in solve.yaml";
  } else {
    s.hint = "see results/detections.csv and results/diagnostics/ for each frame";
  }
  return s;
}

}  // namespace msmcal::solver
