#pragma once
// Stage: image measurement (MSM paper Sec. V-A, "board and dot detection"). Every image of the
// recording is measured once, before anything is decided: the boards it shows and every
// dot-like blob, with what each detector tried and why blobs were refused. Then (Gaussian-fit
// centres) each dot is refitted over a background measured in the other images of its static
// group. Also the plane-level dot selection the later stages share (DotsOnBoard).

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "processing/dataset/recording.h"
#include "processing/solver/solve_types.h"
#include "processing/solver/stages/common.h"
#include "processing/vision/checkerboard.h"
#include "processing/vision/dots.h"

namespace msmcal::solver {

// Stage: image measurement. The boards asked for (in order; step 1: world, sliding; step 2:
// world) and every dot-like blob of one image, with what each detector tried and why blobs were
// refused. Deterministic (reseeds OpenCV's RNG of the calling thread).
struct ImageMeasurement {
  std::vector<std::optional<vision::CheckerboardDetection>> boards;
  std::vector<std::vector<vision::BoardAttempt>> board_attempts;  // per board asked for
  std::vector<vision::Dot> dots;
  vision::DotRejections dot_rejections;
  bool adaptive_dots = false;     // dots from the second, data-driven pass (AdaptiveDotOptions)
  std::string dot_settings;       // that pass's settings, for the frame's note
  size_t dots_on_plane = 0;       // of `dots`, on the plane of the board that carries them
  int second_pass_on_plane = -1;  // what the second pass found there (-1: not run)
  cv::Size image_size;
  int channels = 1, depth_bits = 8;
  // Per board asked for: -1 when found in this image, else the index (in the recording's image
  // list) of the image of the same static scene it was taken from (BorrowSlidingBoards).
  std::vector<int> board_from;
  bool Borrowed(size_t board) const { return board < board_from.size() && board_from[board] >= 0; }
};
// `hints` (optional): per board asked for, where another image of the view found it.
using BoardHints = std::vector<std::optional<vision::BoardHint>>;
ImageMeasurement MeasureImage(const cv::Mat& image, const std::vector<vision::BoardSize>& boards,
                              const vision::DotOptions& dot_options,
                              const vision::CheckerboardOptions& board_options,
                              const BoardHints* hints = nullptr);
// The same, then (PipelineOptions::adaptive_dots) a second, data-driven dot pass where the first
// finds fewer than `expected_dots` on the plane of the board that carries them (step 1: the
// sliding board, boards[1]; step 2: the world board).
ImageMeasurement MeasureFrame(const cv::Mat& image, const std::vector<vision::BoardSize>& boards,
                              int expected_dots, const PipelineOptions& options,
                              const BoardHints* hints = nullptr);

// The hints a measured image gives the other images of its view (one per board asked for; none
// for a board it did not show). Board 0, the world board, is fixed before its view's camera
// (BoardHint::fixed); the sliding board moves between poses.
BoardHints HintsFrom(const ImageMeasurement& m, const vision::CheckerboardOptions& options);

// Where the images of one camera view take their board hints from
// (PipelineOptions::hint_boards_from_first_frame), shared by the solve (MeasureImages) and
// `msmcal solve --explain`. The view's images are measured in rounds, in file order: its first
// image, then the next 2, 4, 8, ..., while some board has no hint yet; then all the others at
// once. An image is measured with the hints known when its round starts; each board's hint is
// that of the first image (in file order) that found it. A view whose first frame misses a board
// (the world board hidden, a spoiled frame) so takes that board's hint from a later frame.
class ViewHints {
 public:
  ViewHints(size_t boards, size_t images);
  // The view positions [begin, end) of the next round; an empty range when every board has a
  // hint or every image was taken: the images from next() on are measured with hints().
  std::pair<size_t, size_t> NextRound();
  // The boards found in the image at `position` (of a round already taken); a round's images are
  // added in file order, once all of them are measured.
  void Add(size_t position, const ImageMeasurement& m, const vision::CheckerboardOptions& options);
  // Per board: the hint, if any (an image measured with every entry empty is measured as
  // without hints).
  const BoardHints& hints() const { return hints_; }
  // The view position of the image each board's hint came from (-1: none yet).
  int source(size_t board) const { return source_.at(board); }
  size_t next() const { return next_; }

 private:
  bool Complete() const;
  size_t images_, next_ = 0;
  BoardHints hints_;
  std::vector<int> source_;
};

// Step 1: the plate does not move within a sliding pose, so a frame of a pose whose sliding
// board was not found (a laser spot on a square corner can break the detectors' grid) takes the
// board of the pose's first frame that shows it (`step1_groups`: the measured images' indices
// per pose; `sizes`: the boards asked for per image), sets board_from and recounts its dots on
// the plate; not a frame that failed the contrast check (a black, blank or saturated frame
// shows no plate). MeasureRecording does this before its dot passes.
void BorrowSlidingBoards(const std::vector<std::vector<size_t>>& step1_groups,
                         const std::vector<std::vector<vision::BoardSize>>& sizes,
                         const PipelineOptions& o, std::vector<ImageMeasurement>* measured);

// Why blobs of a frame were not taken as its laser dots (results/detections.csv).
struct RegionRejections {
  int off_plane = 0;          // outside the board's plane (beyond the margin, on the other board)
  int junction = 0;           // at a square corner, elongated: top-hat residue
  int surface_elongated = 0;  // elongated in the board's plane
};

// Laser dots land on the board's plane: the blobs inside the board's squares area grown by
// `margin_squares` (the plate or screen around the printed pattern), not inside `exclude` (the
// other board's outline, grown by half a square), round in the board's plane.
std::vector<vision::Dot> DotsOnBoard(const std::vector<vision::Dot>& dots,
                                     const vision::CheckerboardDetection& board,
                                     vision::BoardSize size, double margin_squares,
                                     const PipelineOptions& o,
                                     const std::vector<Eigen::Vector2d>& exclude,
                                     RegionRejections* rej);

// The dots of a measured image on the plane of the board that carries them, with the options'
// margins: step 1 (`sizes` has two boards) the sliding board, boards[1], never inside the world
// board's outline; step 2 the world board, boards[0]. The host board must have been found.
std::vector<vision::Dot> DotsOnHostPlane(const std::vector<vision::Dot>& dots,
                                         const ImageMeasurement& m,
                                         const std::vector<vision::BoardSize>& sizes,
                                         const PipelineOptions& options, RegionRejections* rej);

// The frame's dots on its board's plane, and the blobs refused there, into its detection row.
void RecordDots(const std::vector<vision::Dot>& on_plane, const std::vector<vision::Dot>& all,
                const RegionRejections& region, FrameDetection* fd);

// The corners of `board` that no laser dot of the frame disturbs (their average over a view
// leaves the others out).
std::vector<char> CornersClearOfDots(const vision::CheckerboardDetection& board,
                                     const std::vector<vision::Dot>& dots);

// The stage's result: one measurement and one detection row per frame of `recording`, step 1
// frames first, then step 2, each in session.yaml's order.
struct RecordingMeasurement {
  std::vector<ImageMeasurement> images;
  // Boards found (method, square size, corners), blobs and their image-level refusals; the
  // later stages add what they decide.
  std::vector<FrameDetection> detections;
  // Notes: how the dots were centred. Error: the measurement could not go on (an image cannot
  // be read, exposures of one scene differ in size); `images` and `detections` are then empty.
  StageLog log;
  // The dot margins the later stages use: the options', or infinity (the board's whole plane)
  // for a step whose frames show their dots there more often (dot_margin_from_data).
  double step1_dot_margin_squares = 0;
  double step2_dot_margin_squares = 0;
};

// PipelineOptions::dot_margin_from_data, per step (step 1: images asking for two boards; step
// 2: one): the configured margin, or the board's whole plane where more of the step's frames
// (with their host board found) show exactly `expected[i]` dots there than within the margin
// (their `dots_on_plane`, counted with the options' margins).
// Returns the options with the margins taken; recounts dots_on_plane for a step that widened
// and notes why.
PipelineOptions ResolveDotMargins(const std::vector<std::vector<vision::BoardSize>>& sizes,
                                  const std::vector<int>& expected, const PipelineOptions& options,
                                  std::vector<ImageMeasurement>* measured,
                                  std::vector<std::string>* notes);
// Measures every image of `recording` (PipelineOptions::image_threads at a time, OpenCV's own
// parallel loops off meanwhile). `load` is called from several threads at once.
RecordingMeasurement MeasureRecording(const dataset::Recording& recording, const ImageLoader& load,
                                      const PipelineOptions& options);

}  // namespace msmcal::solver
