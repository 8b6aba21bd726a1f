#include "sessions/orchestrator/preview.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <utility>

#include "common/units.h"
#include "processing/vision/checkerboard.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::orchestrator {
namespace {

constexpr int kShift = 4;  // sub-pixel drawing: coordinates in 1/16 px
constexpr double kOne = 1 << kShift;

// Input pixel (centre-of-pixel convention) -> output pixel at scale s, in 1/16 px.
cv::Point ToOut(const Eigen::Vector2d& px, double s) {
  return {static_cast<int>(std::lround(((px.x() + 0.5) * s - 0.5) * kOne)),
          static_cast<int>(std::lround(((px.y() + 0.5) * s - 0.5) * kOne))};
}
cv::Point ToText(const cv::Point& shifted, int dx, int dy) {
  return {shifted.x / static_cast<int>(kOne) + dx, shifted.y / static_cast<int>(kOne) + dy};
}

cv::Mat ToBgr8(const cv::Mat& image) { return vision::ToBgr8(image, "AnnotatePreview"); }

}  // namespace

PreviewLabels MakePreviewLabels(const std::string& file, int step,
                                const dataset::BoardSpec& world_board,
                                const dataset::BoardSpec& sliding_board) {
  PreviewLabels l;
  l.file = file;
  l.step = step;
  if (step == 1) {
    l.board_names = {"sliding board", "world board"};
    l.board_specs = {sliding_board, world_board};
  } else {
    l.board_names = {"world board"};
    l.board_specs = {world_board};
  }
  return l;
}

cv::Mat AnnotatePreview(const cv::Mat& image, const GateResult& gate, const PreviewLabels& labels,
                        int max_width_px) {
  cv::Mat full = ToBgr8(image);
  const double s =
      max_width_px > 0 && full.cols > max_width_px ? double(max_width_px) / full.cols : 1.0;
  cv::Mat out;
  if (s < 1.0) {
    const cv::Size size(max_width_px, std::max(1, static_cast<int>(std::lround(full.rows * s))));
    cv::resize(full, out, size, 0, 0, cv::INTER_AREA);
  } else {
    out = full;
  }
  const int thick = std::max(1, static_cast<int>(std::lround(out.cols / 800.0)));
  const double font = std::max(0.4, 0.7 * out.cols / 1600.0);
  const int font_face = cv::FONT_HERSHEY_SIMPLEX;

  // Boards.
  const cv::Scalar board_colours[] = {cv::Scalar(255, 255, 0), cv::Scalar(0, 200, 255)};
  for (size_t b = 0; b < gate.boards.size(); ++b) {
    if (!gate.boards[b]) continue;
    const auto& corners = gate.boards[b]->corners_px;
    if (corners.empty()) continue;
    const std::string name =
        b < labels.board_names.size() ? labels.board_names[b] : "board " + std::to_string(b);
    // Same colour for the same board in every preview: sliding cyan, world (and others) orange.
    const cv::Scalar colour = board_colours[name.find("sliding") != std::string::npos ? 0 : 1];
    for (const auto& c : corners)
      cv::circle(out, ToOut(c, s), static_cast<int>(2 * thick * kOne), colour, thick, cv::LINE_AA,
                 kShift);
    if (b < labels.board_specs.size()) {
      const int cols = labels.board_specs[b].cols, rows = labels.board_specs[b].rows;
      if (cols > 0 && rows > 0 && corners.size() == static_cast<size_t>(cols * rows)) {
        const std::vector<cv::Point> outline = {ToOut(corners[0], s), ToOut(corners[cols - 1], s),
                                                ToOut(corners[cols * rows - 1], s),
                                                ToOut(corners[(rows - 1) * cols], s)};
        cv::polylines(out, outline, /*isClosed=*/true, colour, thick, cv::LINE_AA, kShift);
        const cv::Point o = ToOut(corners[0], s);
        const cv::Point x = ToOut(corners[std::min(cols - 1, 3)], s);
        const cv::Point y = ToOut(corners[std::min(rows - 1, 3) * cols], s);
        cv::arrowedLine(out, o, x, cv::Scalar(0, 0, 255), 2 * thick, cv::LINE_AA, kShift, 0.2);
        cv::arrowedLine(out, o, y, cv::Scalar(0, 255, 0), 2 * thick, cv::LINE_AA, kShift, 0.2);
        cv::putText(out, "X", ToText(x, 4 * thick, 0), font_face, font, cv::Scalar(0, 0, 255),
                    thick, cv::LINE_AA);
        cv::putText(out, "Y", ToText(y, 4 * thick, 0), font_face, font, cv::Scalar(0, 255, 0),
                    thick, cv::LINE_AA);
      }
    }
    const cv::Point o = ToOut(corners[0], s);
    cv::circle(out, o, static_cast<int>(8 * thick * kOne), colour, 2 * thick, cv::LINE_AA, kShift);
    cv::putText(out, "O " + name, ToText(o, 10 * thick, -10 * thick), font_face, font, colour,
                thick, cv::LINE_AA);
  }

  // Dots: index, fixed ring, 2-sigma ellipse of the centroid covariance (to scale).
  const cv::Scalar dot_colour(0, 0, 255);
  for (size_t i = 0; i < gate.dots.size(); ++i) {
    const auto& d = gate.dots[i];
    const cv::Point c = ToOut(d.px, s);
    cv::circle(out, c, static_cast<int>(6 * thick * kOne), dot_colour, thick, cv::LINE_AA, kShift);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(0.5 * (d.cov_px2 + d.cov_px2.transpose()));
    const Eigen::Vector2d lambda = eig.eigenvalues().cwiseMax(0.0);
    const Eigen::Vector2d major = eig.eigenvectors().col(1);
    const double angle_deg = common::RadToDeg(std::atan2(major.y(), major.x()));
    const int a = std::max(1, static_cast<int>(std::lround(2 * std::sqrt(lambda(1)) * s * kOne)));
    const int b = std::max(1, static_cast<int>(std::lround(2 * std::sqrt(lambda(0)) * s * kOne)));
    cv::ellipse(out, c, cv::Size(a, b), angle_deg, 0, 360, cv::Scalar(0, 255, 255), 1, cv::LINE_AA,
                kShift);
    cv::putText(out, std::to_string(i), ToText(c, 8 * thick, -8 * thick), font_face, font,
                dot_colour, thick, cv::LINE_AA);
  }

  // Banner.
  char figures[160];
  std::snprintf(figures, sizeof(figures), "dots %d/%d  saturated %.2f%%", gate.dots_found,
                gate.dots_expected, 100.0 * gate.saturated_fraction);
  const std::string line1 = labels.file + "  step " + std::to_string(labels.step) + "  " +
                            (gate.accepted ? "ACCEPTED" : "REJECTED") + "  " + figures;
  const std::string line2 = gate.accepted ? std::string() : gate.reason;
  int base = 0;
  const cv::Size text = cv::getTextSize(line1, font_face, font, thick, &base);
  const int line_h = text.height + base + 4 * thick;
  const int banner_h = std::min(out.rows, line_h * (line2.empty() ? 1 : 2) + 4 * thick);
  cv::rectangle(out, cv::Rect(0, 0, out.cols, banner_h), cv::Scalar(32, 32, 32), cv::FILLED);
  const cv::Scalar text_colour = gate.accepted ? cv::Scalar(80, 255, 80) : cv::Scalar(80, 80, 255);
  cv::putText(out, line1, cv::Point(4 * thick, line_h - base), font_face, font, text_colour, thick,
              cv::LINE_AA);
  if (!line2.empty())
    cv::putText(out, line2, cv::Point(4 * thick, 2 * line_h - base), font_face, font, text_colour,
                thick, cv::LINE_AA);
  return out;
}

std::string PreviewFileName(const std::string& file) {
  std::string name = file;
  for (char& c : name) c = c == '/' ? '_' : c;
  const size_t dot = name.rfind('.');
  const size_t us = name.rfind('_');
  if (dot != std::string::npos && (us == std::string::npos || dot > us)) name.erase(dot);
  return name + ".jpg";
}

std::filesystem::path WritePreview(const std::filesystem::path& session_dir,
                                   const std::string& file, const cv::Mat& annotated) {
  const std::filesystem::path path = session_dir / "previews" / PreviewFileName(file);
  std::vector<uchar> bytes;
  if (annotated.empty() || !cv::imencode(".jpg", annotated, bytes, {cv::IMWRITE_JPEG_QUALITY, 90}))
    throw std::runtime_error(path.string() + ": cannot encode the preview as JPEG");
  try {
    interchange::WriteFileAtomically(path, std::string(bytes.begin(), bytes.end()));
  } catch (const std::exception& e) {
    throw std::runtime_error(path.string() + ": " + e.what());
  }
  return path;
}

FrameObserver MakePreviewWriter(const std::filesystem::path& session_dir,
                                const dataset::BoardSpec& world_board,
                                const dataset::BoardSpec& sliding_board,
                                std::function<void(const std::string&)> warn) {
  return [session_dir, world_board, sliding_board, warn = std::move(warn)](const FrameReport& r) {
    if (!r.accepted || r.image == nullptr || r.image->empty()) return;
    try {
      GateResult no_gate;  // gate off: accepted without figures
      no_gate.accepted = true;
      const cv::Mat annotated =
          AnnotatePreview(*r.image, r.gate ? *r.gate : no_gate,
                          MakePreviewLabels(r.file, r.step, world_board, sliding_board));
      WritePreview(session_dir, r.file, annotated);
    } catch (const std::exception& e) {
      if (warn) warn(std::string("preview of ") + r.file + " not written: " + e.what());
    }
  };
}

}  // namespace msmcal::orchestrator
