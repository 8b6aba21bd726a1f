#include "sessions/live_view/live_view.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <stdexcept>
#include <system_error>
#include <utility>

#include "processing/vision/checkerboard.h"
#include "sessions/orchestrator/console_operator.h"
#include "sessions/orchestrator/preview.h"

namespace msmcal::live_view {

namespace {

// Live images a second at most while a Hall recording runs (LiveView::ProcessLiveFrame).
constexpr double kRecordingLiveFps = 2.0;

using Clock = std::chrono::steady_clock;

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// 128 random bits as hex, from the system's entropy source.
std::string RandomToken() {
  std::random_device rd;
  std::string s;
  static const char kHex[] = "0123456789abcdef";
  for (int i = 0; i < 4; ++i) {
    uint32_t v = rd();
    for (int k = 0; k < 8; ++k, v >>= 4) s += kHex[v & 15];
  }
  return s;
}

int ExpectedDots(const dataset::Recording& plan, int step, size_t index) {
  if (step == 1 && index < plan.step1.size())
    return static_cast<int>(plan.step1[index].beams.size());
  if (step == 2 && index < plan.step2.size()) {
    const auto& f = plan.step2[index];
    return static_cast<int>(f.beams.size() * std::max<size_t>(1, f.triggers.size()));
  }
  return 0;
}

// Draws the region where the gate expects the dots (the board plane's visible area: the squares
// outline of the sliding board in step 1, of the world board in step 2, grown by the gate's
// margin) onto `out`, which shows the detection image scaled by out.cols / image_cols.
void DrawExpectedRegion(cv::Mat& out, int image_cols, const orchestrator::GateResult& gate,
                        int step, const dataset::Recording& plan, double margin_squares) {
  if (step != 1 && step != 2) return;
  if (gate.boards.empty() || !gate.boards[0]) return;
  const dataset::BoardSpec& spec = step == 1 ? plan.sliding_board : plan.world_board;
  const auto outline =
      vision::SquaresOutline(*gate.boards[0], {spec.cols, spec.rows}, margin_squares);
  if (outline.size() < 3) return;
  const double s = static_cast<double>(out.cols) / image_cols;
  std::vector<cv::Point> poly;
  for (const auto& p : outline)
    poly.emplace_back(static_cast<int>(std::lround(p.x() * s)),
                      static_cast<int>(std::lround(p.y() * s)));
  const cv::Scalar magenta(255, 0, 255);
  const int thick = std::max(1, out.cols / 800);
  // Dashed: every other segment of each edge split in 12.
  for (size_t i = 0; i < poly.size(); ++i) {
    const cv::Point a = poly[i], b = poly[(i + 1) % poly.size()];
    for (int k = 0; k < 12; k += 2) {
      const cv::Point p = a + (b - a) * k / 12, q = a + (b - a) * (k + 1) / 12;
      cv::line(out, p, q, magenta, thick, cv::LINE_AA);
    }
  }
  const auto top = std::min_element(
      poly.begin(), poly.end(), [](const cv::Point& a, const cv::Point& b) { return a.y < b.y; });
  cv::putText(out, "dots expected here", *top + cv::Point(4, -6), cv::FONT_HERSHEY_SIMPLEX,
              std::max(0.4, 0.5 * out.cols / 960.0), magenta, thick, cv::LINE_AA);
}

std::string EncodeJpeg(const cv::Mat& image, int quality) {
  std::vector<uchar> bytes;
  if (!cv::imencode(".jpg", image, bytes, {cv::IMWRITE_JPEG_QUALITY, quality}))
    throw std::runtime_error("live view: cannot encode the image as JPEG");
  return std::string(bytes.begin(), bytes.end());
}

}  // namespace

const char* ToString(SessionState state) {
  switch (state) {
    case SessionState::kRunning:
      return "running";
    case SessionState::kWaiting:
      return "waiting";
    case SessionState::kDone:
      return "done";
    case SessionState::kAborted:
      return "aborted";
  }
  return "?";
}

const char* ToString(Command command) {
  switch (command) {
    case Command::kReady:
      return "ready";
    case Command::kRepeat:
      return "repeat";
    case Command::kAbort:
      return "abort";
  }
  return "?";
}

std::string LiveViewOptions::Validate() const {
  if (image_max_width_px < 64)
    return "LiveViewOptions.image_max_width_px = " + std::to_string(image_max_width_px) +
           ": must be >= 64";
  if (jpeg_quality < 1 || jpeg_quality > 100)
    return "LiveViewOptions.jpeg_quality = " + std::to_string(jpeg_quality) +
           ": must be in [1, 100]";
  if (!(max_live_fps > 0) || !std::isfinite(max_live_fps))
    return "LiveViewOptions.max_live_fps = " + std::to_string(max_live_fps) + ": must be > 0";
  if (controller_lease.count() <= 0)
    return "LiveViewOptions.controller_lease = " + std::to_string(controller_lease.count()) +
           " ms: must be > 0";
  if (std::string e = gate.Validate(); !e.empty()) return "LiveViewOptions.gate: " + e;
  return {};
}

struct LiveView::Figures {
  orchestrator::LiveTotals totals;
  int frames_total = 0;
  int frames_done = 0;  // final decisions
  std::string last_line;
  nlohmann::json recent = nlohmann::json::array();  // last decisions, newest first
  nlohmann::json live = nlohmann::json::object();   // what the gate sees in the live image
  Clock::time_point first_decision{};
  Clock::time_point last_decision{};
};

LiveView::LiveView(const dataset::Recording& plan, LiveViewOptions options)
    : plan_(plan), options_(std::move(options)), started_(Clock::now()) {
  if (std::string e = options_.Validate(); !e.empty()) throw std::invalid_argument(e);
  figures_ = std::make_unique<Figures>();
  figures_->frames_total = static_cast<int>(plan_.step1.size() + plan_.step2.size());
}

LiveView::~LiveView() = default;

void LiveView::Changed() {
  ++version_;
  cv_.notify_all();
}

orchestrator::FrameObserver LiveView::MakeFrameObserver() {
  return [this](const orchestrator::FrameReport& r) { ProcessDecision(r); };
}

orchestrator::LiveFrameObserver LiveView::MakeLiveFrameObserver() {
  return [this](const orchestrator::LiveFrame& f) { ProcessLiveFrame(f); };
}

orchestrator::RigStatusObserver LiveView::MakeRigStatusObserver() {
  return [this](const orchestrator::RigStatus& st) {
    std::lock_guard<std::mutex> lock(mu_);
    const Clock::time_point now = Clock::now();
    if (!st.hall_recording.empty() && st.hall_recording == rig_.hall_recording && now > rig_seen_ &&
        st.hall_readings >= rig_.hall_readings)
      hall_rate_per_s_ = (st.hall_readings - rig_.hall_readings) / Seconds(now - rig_seen_);
    else if (st.hall_recording.empty())
      hall_rate_per_s_ = 0;
    rig_ = st;
    rig_seen_ = now;
    Changed();
  };
}

void LiveView::AddLogLine(const std::string& line) {
  std::lock_guard<std::mutex> lock(mu_);
  log_.push_back(line);
  if (log_.size() > options_.log_lines) log_.erase(log_.begin());
  Changed();
}

void LiveView::SetState(SessionState state, const std::string& message) {
  std::lock_guard<std::mutex> lock(mu_);
  state_ = state;
  state_message_ = message;
  if (state == SessionState::kDone || state == SessionState::kAborted) waiting_ = false;
  Changed();
}

Command LiveView::Ask(const Prompt& prompt) {
  std::unique_lock<std::mutex> lock(mu_);
  prompt_ = prompt;
  ++prompt_id_;
  repeats_ = 0;
  answer_.reset();
  if (abort_requested_ || closed_) return Command::kAbort;
  waiting_ = true;
  state_ = SessionState::kWaiting;
  state_message_.clear();
  Changed();
  cv_.wait(lock, [this] { return closed_ || answer_.has_value(); });
  waiting_ = false;
  const Command c = closed_ ? Command::kAbort : *answer_;
  answer_.reset();
  if (c == Command::kReady) state_ = SessionState::kRunning;
  Changed();
  return c;
}

bool LiveView::AbortRequested() const {
  std::lock_guard<std::mutex> lock(mu_);
  return abort_requested_;
}

void LiveView::Close() {
  std::lock_guard<std::mutex> lock(mu_);
  closed_ = true;
  Changed();
}

std::chrono::milliseconds LiveView::keepalive_interval() const {
  return std::min(std::chrono::milliseconds(1000), options_.controller_lease / 4);
}

bool LiveView::closed() const {
  std::lock_guard<std::mutex> lock(mu_);
  return closed_;
}

bool LiveView::ControllerActive(Clock::time_point now) const {
  return !controller_token_.empty() && now - controller_seen_ < options_.controller_lease;
}

Reply LiveView::Claim(const std::string& previous) {
  std::lock_guard<std::mutex> lock(mu_);
  const Clock::time_point now = Clock::now();
  Reply r;
  if (!previous.empty() && previous == controller_token_) {
    controller_seen_ = now;
    r.controller_token = controller_token_;
    return r;
  }
  if (ControllerActive(now)) {
    r.http_status = 409;
    r.error = "another page controls this session; this page watches";
    return r;
  }
  controller_token_ = RandomToken();
  controller_seen_ = now;
  r.controller_token = controller_token_;
  Changed();
  return r;
}

void LiveView::SeeController(const std::string& token) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!token.empty() && token == controller_token_) controller_seen_ = Clock::now();
}

Reply LiveView::Submit(const std::string& token, Command command, int64_t prompt_id) {
  std::lock_guard<std::mutex> lock(mu_);
  Reply r;
  if (token.empty() || token != controller_token_ || !ControllerActive(Clock::now())) {
    r.http_status = 403;
    r.error = "this page does not control the session (claim control first)";
    return r;
  }
  controller_seen_ = Clock::now();
  if (state_ == SessionState::kDone || state_ == SessionState::kAborted) {
    r.http_status = 409;
    r.error = std::string("the session has ended (") + ToString(state_) + ")";
    return r;
  }
  if (command == Command::kAbort) {
    abort_requested_ = true;
    if (waiting_) answer_ = Command::kAbort;
    state_message_ = "abort requested: switching to the safe state";
    Changed();
    return r;
  }
  if (!waiting_ || prompt_id != prompt_id_) {
    r.http_status = 409;
    r.error = waiting_ ? "prompt " + std::to_string(prompt_id) + " is not the one shown (" +
                             std::to_string(prompt_id_) + ")"
                       : "no instruction is waiting for an answer";
    return r;
  }
  if (command == Command::kRepeat) {
    ++repeats_;  // the page shows the block again; the prompt keeps waiting
  } else {
    answer_ = command;
  }
  Changed();
  return r;
}

void LiveView::PublishImage(std::string jpeg) {
  auto bytes = std::make_shared<const std::string>(std::move(jpeg));
  std::lock_guard<std::mutex> lock(mu_);
  image_ = std::move(bytes);
  ++image_sequence_;
  Changed();
}

std::shared_ptr<const std::string> LiveView::Image(uint64_t* sequence) const {
  std::lock_guard<std::mutex> lock(mu_);
  if (sequence) *sequence = image_sequence_;
  return image_;
}

uint64_t LiveView::WaitForChange(uint64_t version, std::chrono::milliseconds timeout) const {
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait_for(lock, timeout, [&] { return closed_ || version_ != version; });
  return version_;
}

uint64_t LiveView::version() const {
  std::lock_guard<std::mutex> lock(mu_);
  return version_;
}

void LiveView::ProcessLiveFrame(const orchestrator::LiveFrame& f) {
  if (!f.image || f.image->empty()) return;
  std::string recording;  // a Hall recording running (the background one: frames are free)
  {
    std::lock_guard<std::mutex> lock(mu_);
    // The pump's own word first: the rig's status reports the recording only once it runs,
    // and a frame taken for a set-up gets the (slow) board search.
    if (f.step == 0) recording = f.hall_recording.empty() ? rig_.hall_recording : f.hall_recording;
    // During a recording at most 2 images a second, without the board search: the camera image
    // only, so the host's CPU stays with the recording.
    const double fps = recording.empty() ? options_.max_live_fps
                                         : std::min(options_.max_live_fps, kRecordingLiveFps);
    const Clock::time_point now = Clock::now();
    if (now - last_live_ < std::chrono::duration<double>(1.0 / fps)) return;
    last_live_ = now;
  }
  cv::Mat image = *f.image;
  if (options_.detect_max_width_px > 0 && image.cols > options_.detect_max_width_px) {
    const double s = static_cast<double>(options_.detect_max_width_px) / image.cols;
    cv::Mat small;
    cv::resize(image, small, cv::Size(), s, s, cv::INTER_AREA);
    image = small;
  }
  orchestrator::GateResult g;
  std::string caption;
  const int step = f.step;
  if (step == 1 || step == 2) {
    g = orchestrator::CheckFrame(image, step, ExpectedDots(plan_, step, f.index), plan_.world_board,
                                 plan_.sliding_board, options_.gate);
    const std::string& file =
        step == 1 ? plan_.step1.at(f.index).file : plan_.step2.at(f.index).file;
    caption = "LIVE " + file;
  } else if (!recording.empty()) {
    g.accepted = true;
    caption = "LIVE (Hall " + recording + " recording running: camera image only)";
  } else {
    // A Hall recording's set-up: the boards only (no frame with expected dots follows directly).
    g.boards = {vision::DetectCheckerboard(image, {plan_.world_board.cols, plan_.world_board.rows},
                                           options_.gate.boards)};
    g.accepted = true;
    caption = "LIVE (Hall recording set-up)";
  }
  const orchestrator::PreviewLabels labels = orchestrator::MakePreviewLabels(
      caption, step == 1 ? 1 : 2, plan_.world_board, plan_.sliding_board);
  cv::Mat out = orchestrator::AnnotatePreview(image, g, labels, options_.image_max_width_px);
  DrawExpectedRegion(out, image.cols, g, step, plan_, options_.gate.MarginSquares(step));
  nlohmann::json live;
  live["source"] = "live";
  live["caption"] = caption;
  live["step"] = step;
  nlohmann::json boards = nlohmann::json::array();
  for (const auto& b : g.boards) boards.push_back(b.has_value());
  live["boards_found"] = boards;
  live["dots_found"] = g.dots_found;
  live["dots_expected"] = g.dots_expected;
  live["gate_would_accept"] = g.accepted;
  live["reason"] = g.reason;
  std::string jpeg = EncodeJpeg(out, options_.jpeg_quality);
  {
    std::lock_guard<std::mutex> lock(mu_);
    figures_->live = std::move(live);
  }
  PublishImage(std::move(jpeg));
}

void LiveView::ProcessDecision(const orchestrator::FrameReport& r) {
  std::string jpeg;
  if (r.image && !r.image->empty()) {
    orchestrator::GateResult no_gate;
    no_gate.accepted = r.accepted;
    const orchestrator::GateResult& g = r.gate ? *r.gate : no_gate;
    cv::Mat out = orchestrator::AnnotatePreview(
        *r.image, g,
        orchestrator::MakePreviewLabels(r.file, r.step, plan_.world_board, plan_.sliding_board),
        options_.image_max_width_px);
    DrawExpectedRegion(out, r.image->cols, g, r.step, plan_, options_.gate.MarginSquares(r.step));
    jpeg = EncodeJpeg(out, options_.jpeg_quality);
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    Figures& fg = *figures_;
    if (r.accepted)
      ++fg.totals.accepted;
    else if (r.final)
      ++fg.totals.rejected;
    else
      ++fg.totals.retried;
    const Clock::time_point now = Clock::now();
    if (r.final) {
      if (fg.frames_done == 0) fg.first_decision = now;
      ++fg.frames_done;
      fg.last_decision = now;
    }
    fg.last_line = orchestrator::FormatLiveFigures(r, fg.totals);
    nlohmann::json d;
    d["file"] = r.file;
    d["step"] = r.step;
    d["attempt"] = r.attempt + 1;
    d["decision"] = r.accepted ? "accepted" : (r.final ? "rejected" : "retry");
    d["reason"] = r.accepted || !r.gate ? std::string() : r.gate->reason;
    if (r.gate) {
      d["dots_found"] = r.gate->dots_found;
      d["dots_expected"] = r.gate->dots_expected;
      d["saturated_percent"] = 100.0 * r.gate->saturated_fraction;
    }
    fg.recent.insert(fg.recent.begin(), d);
    if (fg.recent.size() > 8) fg.recent.erase(fg.recent.size() - 1);
    nlohmann::json live;
    live["source"] = "decision";
    live["caption"] = r.file + (r.accepted ? " ACCEPTED" : " REJECTED");
    live["step"] = r.step;
    fg.live = std::move(live);
    Changed();
  }
  if (!jpeg.empty()) PublishImage(std::move(jpeg));
}

std::string LiveView::StateJson() const {
  std::lock_guard<std::mutex> lock(mu_);
  const Clock::time_point now = Clock::now();
  nlohmann::json j;
  j["state"] = ToString(state_);
  j["message"] = state_message_;
  j["version"] = version_;
  nlohmann::json p;
  p["id"] = prompt_id_;
  p["waiting"] = waiting_;
  p["title"] = prompt_.title;
  p["instructions"] = prompt_.instructions;
  p["setup"] = prompt_.setup_json.empty()
                   ? nlohmann::json()
                   : nlohmann::json::parse(prompt_.setup_json, nullptr, /*allow_exceptions=*/false);
  p["number"] = prompt_.number;
  p["total"] = prompt_.total;
  p["repeats"] = repeats_;
  p["step"] = prompt_.step;
  p["frame"] = prompt_.step == 0 ? 0 : prompt_.index + 1;
  p["frames_in_step"] = prompt_.step == 1   ? plan_.step1.size()
                        : prompt_.step == 2 ? plan_.step2.size()
                                            : 0;
  j["prompt"] = p;
  const Figures& fg = *figures_;
  nlohmann::json pr;
  pr["frames_done"] = fg.frames_done;
  pr["frames_total"] = fg.frames_total;
  pr["fraction"] = fg.frames_total > 0 ? static_cast<double>(fg.frames_done) / fg.frames_total : 0;
  pr["elapsed_s"] = Seconds(now - started_);
  // ETA: the mean time per frame decided so far (operator time included) times the frames left.
  if (fg.frames_done > 0 && state_ != SessionState::kDone && state_ != SessionState::kAborted) {
    const double per_frame = Seconds(fg.last_decision - started_) / fg.frames_done;
    pr["eta_s"] = per_frame * (fg.frames_total - fg.frames_done);
  } else {
    pr["eta_s"] = nullptr;
  }
  j["progress"] = pr;
  nlohmann::json f;
  f["accepted"] = fg.totals.accepted;
  f["rejected"] = fg.totals.rejected;
  f["retried"] = fg.totals.retried;
  f["last"] = fg.last_line;
  f["recent"] = fg.recent;
  j["figures"] = f;
  j["live"] = fg.live;
  j["image"] = {{"sequence", image_sequence_}};
  if (!options_.disk_path.empty() &&
      (disk_free_bytes_ < 0 || now - disk_checked_ > std::chrono::seconds(2))) {
    std::error_code ec;
    const auto space = std::filesystem::space(options_.disk_path, ec);
    disk_free_bytes_ = ec ? -1 : static_cast<double>(space.available);
    disk_checked_ = now;
  }
  nlohmann::json rig;
  rig["outputs_on"] = rig_.outputs_on;
  rig["reference_locked"] = rig_.reference_locked;
  rig["hall_recording"] = rig_.hall_recording;
  rig["hall_readings"] = rig_.hall_readings;
  rig["hall_readings_per_s"] = hall_rate_per_s_;
  rig["hall_lost"] = rig_.hall_lost;
  rig["disk_free_bytes"] =
      disk_free_bytes_ >= 0 ? nlohmann::json(disk_free_bytes_) : nlohmann::json();
  j["rig"] = rig;
  j["controller"] = {{"active", ControllerActive(now)}};
  j["abort_requested"] = abort_requested_;
  j["log"] = log_;
  return j.dump();
}

}  // namespace msmcal::live_view
