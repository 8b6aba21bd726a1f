#include "simulation/twin/physical_twin.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <mutex>
#include <numbers>
#include <random>
#include <stdexcept>
#include <thread>

#include "mocks/camera/mock_gv_camera.h"
#include "mocks/camera/place_image.h"
#include "mocks/generator/mock_server.h"
#include "mocks/mcu/mock_mcu.h"
#include "mocks/rig/hall_model.h"
#include "mocks/rig/mirror_motion.h"
#include "mocks/rig/truth_io.h"

namespace msmcal::twin {
namespace fs = std::filesystem;

namespace {

// A generator output that plays: on, started (not armed waiting for its trigger), not gated.
bool Playing(const sim::ChannelSignal& c) { return c.output_on && c.running && !c.burst_gated; }

double StartPhaseDeg(const sim::ChannelSignal& c) {
  return c.burst_on ? c.burst_phase_deg : c.phase_deg;
}

// Most pattern repetitions one pulse is traced through within one window.
constexpr int64_t kMaxRepeats = 64;

}  // namespace

std::string PhysicalTwinOptions::Validate() const {
  if (std::string e = sim.Validate(); !e.empty()) return "PhysicalTwinOptions.sim: " + e;
  for (int p : {port1, port2})
    if (p < 0 || p > 65535)
      return "PhysicalTwinOptions.port = " + std::to_string(p) + ": must be in [0, 65535]";
  if (!(camera_frame_rate_hz > 0 && camera_frame_rate_hz <= 1000))
    return "PhysicalTwinOptions.camera_frame_rate_hz = " + std::to_string(camera_frame_rate_hz) +
           ": must be in (0, 1000]";
  if (!(exposure_s > 0 && exposure_s <= 60))
    return "PhysicalTwinOptions.exposure_s = " + std::to_string(exposure_s) +
           ": must be in (0, 60]";
  if (hall_rate_hz == 0) return "PhysicalTwinOptions.hall_rate_hz = 0: must be > 0";
  return {};
}

// The drives as physics: the resonator and Hall models for one applied drive.
struct Physics {
  AppliedDrive drive;
  std::unique_ptr<sim::MirrorMotion> motion;
  std::unique_ptr<sim::HallModel> hall;
  int64_t period_ns = 0;  // the drives' common period when a whole number of ns, else 0
  // Generator time of a twin-clock instant, reduced modulo the drives' period in integers first
  // (hours of running do not cost the pose its precision).
  double GeneratorTimeS(int64_t t_ns) const {
    int64_t dt = t_ns - drive.t0_ns;
    if (period_ns > 0) {
      dt %= period_ns;
      if (dt < 0) dt += period_ns;
    }
    return static_cast<double>(dt) * 1e-9;
  }
  geometry::MirrorPose PoseAtNs(int64_t t_ns) const {
    return motion->PoseAt(GeneratorTimeS(t_ns), drive.mode);
  }
};

// The laser pattern decoded from an arb: rising-edge sample indices.
struct LaserPattern {
  bool playing = false;
  std::vector<int64_t> rising;  // sample indices, ascending
  double period_s = 0;          // points / sample rate
  double rate_sps = 0;
  double phase_cycles = 0;
  int64_t start_ns = 0;
  // Twin-clock time of the m-th repetition of pulse k.
  int64_t FireNs(size_t k, int64_t m) const {
    const double t = (static_cast<double>(rising[k]) / rate_sps - phase_cycles * period_s) +
                     static_cast<double>(m) * period_s;
    return start_ns + static_cast<int64_t>(std::llround(t * 1e9));
  }
};

struct PhysicalTwin::Impl {
  PhysicalTwinOptions options;
  std::function<int64_t()> clock;
  int64_t origin_ns = 0;
  std::shared_ptr<const sim::RigSimulator> sim;
  std::unique_ptr<sim::MockGeneratorPair> generators;
  std::unique_ptr<sim::MockGvCamera> camera;
  // The served camera, for its exposure register (set once serving, read on its frame thread).
  std::atomic<const sim::MockGvCamera*> served_camera{nullptr};
  std::unique_ptr<sim::MockMcu> mcu;
  std::string hall_device;

  mutable std::mutex state_mu;
  TwinState state;
  uint64_t generation = 0;

  mutable std::mutex physics_mu;
  mutable std::shared_ptr<const Physics> physics;
  mutable const void* laser_arb = nullptr;  // identity of the decoded arb
  mutable std::vector<int64_t> laser_rising;

  // The last drive and laser pattern seen all running (for the truth).
  mutable std::mutex applied_mu;
  mutable std::optional<AppliedDrive> applied_drive;
  mutable std::vector<double> applied_times;

  std::mutex render_mu;
  std::vector<render::SceneDot> last_dots;
  std::vector<geometry::Rigid3d> last_boards;
  cv::Mat last_image;
  bool have_image = false;

  std::function<HandsReply(const std::string&)> handler;
  class HallSource;

  // Samples what the generators play every 20 ms, so that the truth knows the last drive and
  // trigger table applied even when no frame or reading was taken while they ran.
  std::thread watch_thread;
  std::mutex watch_mu;
  std::condition_variable watch_cv;
  bool watch_stop = false;
  void Watch() {
    std::unique_lock lock(watch_mu);
    while (!watch_cv.wait_for(lock, std::chrono::milliseconds(20), [&] { return watch_stop; })) {
      lock.unlock();
      NoteApplied(*CurrentPhysics(), CurrentLaser());
      lock.lock();
    }
  }

  int listen_fd = -1;
  int stop_pipe[2] = {-1, -1};
  std::thread hands_thread;

  int64_t Now() const { return clock(); }

  AppliedDrive ReadDrive() const {
    AppliedDrive d;
    d.mirror = options.sim.mirror;
    const sim::ChannelSignal f = generators->unit(1).Signal(1);
    const sim::ChannelSignal s = generators->unit(1).Signal(2);
    d.fast_on = Playing(f) && f.function == sim::Function::kSin;
    d.slow_on = Playing(s) && s.function == sim::Function::kSin;
    d.t0_ns = d.fast_on ? f.start_time_ns : d.slow_on ? s.start_time_ns : 0;
    auto axis = [&](const sim::ChannelSignal& c, sim::AxisOptions* a, bool on) {
      if (!on) {
        a->amplitude_vpp = 0;
        return;
      }
      a->frequency_hz = c.frequency_hz;
      a->amplitude_vpp = c.amplitude_vpp;
      // Phase at generator time 0 (the channels may have started at different instants).
      const double shift =
          360.0 * c.frequency_hz * static_cast<double>(d.t0_ns - c.start_time_ns) * 1e-9;
      a->phase_deg = std::fmod(StartPhaseDeg(c) + shift, 360.0);
    };
    axis(f, &d.mirror.fast, d.fast_on);
    axis(s, &d.mirror.slow, d.slow_on);
    d.mode = d.fast_on && d.slow_on ? sim::DriveMode::kScan
             : d.fast_on            ? sim::DriveMode::kFastOnly
             : d.slow_on            ? sim::DriveMode::kScan
                                    : sim::DriveMode::kOff;
    return d;
  }

  static bool SameDrive(const AppliedDrive& a, const AppliedDrive& b) {
    auto same = [](const sim::AxisOptions& x, const sim::AxisOptions& y) {
      return x.frequency_hz == y.frequency_hz && x.amplitude_vpp == y.amplitude_vpp &&
             x.phase_deg == y.phase_deg;
    };
    return a.fast_on == b.fast_on && a.slow_on == b.slow_on && a.mode == b.mode &&
           a.t0_ns == b.t0_ns && same(a.mirror.fast, b.mirror.fast) &&
           same(a.mirror.slow, b.mirror.slow);
  }

  std::shared_ptr<const Physics> CurrentPhysics() const {
    const AppliedDrive d = ReadDrive();
    std::lock_guard lock(physics_mu);
    if (!physics || !SameDrive(physics->drive, d)) {
      auto p = std::make_shared<Physics>();
      p->drive = d;
      p->motion = std::make_unique<sim::MirrorMotion>(d.mirror);
      sim::SimOptions o = options.sim;
      o.mirror = d.mirror;
      p->hall = std::make_unique<sim::HallModel>(o);
      const double period_ns = o.PatternPeriodS() * 1e9;
      if (period_ns >= 1 && std::abs(period_ns - std::round(period_ns)) < 1e-3)
        p->period_ns = std::llround(period_ns);
      physics = std::move(p);
    }
    return physics;
  }

  LaserPattern CurrentLaser() const {
    LaserPattern lp;
    const sim::ChannelSignal c = generators->unit(2).Signal(1);
    if (!Playing(c) || c.function != sim::Function::kArb || !c.arb_samples ||
        c.arb_samples->empty() || !(c.arb_sample_rate_sps > 0))
      return lp;
    lp.playing = true;
    lp.rate_sps = c.arb_sample_rate_sps;
    lp.period_s = static_cast<double>(c.arb_samples->size()) / c.arb_sample_rate_sps;
    lp.phase_cycles = StartPhaseDeg(c) / 360.0;
    lp.start_ns = c.start_time_ns;
    std::lock_guard lock(physics_mu);
    if (laser_arb != c.arb_samples.get()) {
      // Rising edges of the uploaded samples (cyclic), the light pulses of a TTL-triggered
      // laser; an inverted output fires on the samples' falling edges.
      const auto& s = *c.arb_samples;
      const bool inverted = c.output_polarity == "INV";
      auto high = [&](size_t i) { return inverted ? s[i] < 0 : s[i] > 0; };
      laser_rising.clear();
      for (size_t i = 0; i < s.size(); ++i)
        if (high(i) && !high((i + s.size() - 1) % s.size()))
          laser_rising.push_back(static_cast<int64_t>(i));
      laser_arb = c.arb_samples.get();
    }
    lp.rising = laser_rising;
    return lp;
  }

  // Pattern times (generator time modulo the arb period) of the laser's pulses.
  std::vector<double> PatternTimes(const LaserPattern& lp, int64_t t0_ns) const {
    std::vector<double> t;
    for (size_t k = 0; k < lp.rising.size(); ++k) {
      double x = std::fmod(static_cast<double>(lp.FireNs(k, 0) - t0_ns) * 1e-9, lp.period_s);
      if (x < 0) x += lp.period_s;
      t.push_back(std::round(x * 1e12) / 1e12);
    }
    std::sort(t.begin(), t.end());
    return t;
  }

  void NoteApplied(const Physics& p, const LaserPattern& lp) const {
    if (p.drive.mode != sim::DriveMode::kScan || !p.drive.fast_on || !lp.playing ||
        lp.rising.empty())
      return;
    std::vector<double> times = PatternTimes(lp, p.drive.t0_ns);
    std::lock_guard lock(applied_mu);
    // Under the same drive (same start), the table is every pulse played while scanning: a
    // session plays each frame's triggers in turn (docs/twin.md, "The truth").
    if (applied_drive && SameDrive(*applied_drive, p.drive)) {
      for (double t : applied_times) {
        const bool seen = std::any_of(times.begin(), times.end(),
                                      [t](double u) { return std::abs(u - t) < 1e-9; });
        if (!seen) times.push_back(t);
      }
      std::sort(times.begin(), times.end());
    }
    applied_drive = p.drive;
    applied_times = std::move(times);
  }

  std::vector<sim::PulseAtPose> Pulses(int64_t from_ns, int64_t to_ns) const {
    std::vector<sim::PulseAtPose> out;
    const std::shared_ptr<const Physics> p = CurrentPhysics();
    const LaserPattern lp = CurrentLaser();
    NoteApplied(*p, lp);
    if (!lp.playing || lp.rising.empty() || to_ns < lp.start_ns) return out;
    const double period_ns = lp.period_s * 1e9;
    for (size_t k = 0; k < lp.rising.size(); ++k) {
      const int64_t base = lp.FireNs(k, 0);
      int64_t m_lo = static_cast<int64_t>(
          std::ceil(static_cast<double>(std::max(from_ns, lp.start_ns) - base) / period_ns));
      const int64_t m_hi =
          static_cast<int64_t>(std::floor(static_cast<double>(to_ns - base) / period_ns));
      m_lo = std::max(m_lo, m_hi - kMaxRepeats + 1);
      for (int64_t m = m_lo; m <= m_hi; ++m) {
        const int64_t t = lp.FireNs(k, m);
        if (t < from_ns || t > to_ns || t < lp.start_ns) continue;
        out.push_back({static_cast<int>(k), p->PoseAtNs(t)});
      }
    }
    return out;
  }

  sim::RigState ToRigState(const TwinState& s) const {
    sim::RigState r;
    r.camera = s.camera;
    r.msm_mounted = s.msm_mounted;
    r.unblocked_beams = s.beams_unblocked;
    if (s.sliding_plate && s.sliding_plate->mounted)
      r.world_from_sliding = sim->SlidingPose(s.sliding_plate->pose, s.sliding_plate->distance_mm,
                                              s.sliding_plate->tilt_deg);
    return r;
  }

  mutable std::mutex stamps_mu;
  std::deque<std::pair<int64_t, FrameStamp>> stamps;  // (device timestamp, stamp)

  // The camera's exposure once its client set one (GenICam ExposureTime), else --exposure.
  int64_t ExposureNs() const {
    if (const sim::MockGvCamera* cam = served_camera.load())
      if (const std::optional<double> us = cam->ClientExposureUs())
        return static_cast<int64_t>(std::llround(*us * 1e3));
    return static_cast<int64_t>(options.exposure_s * 1e9);
  }

  sim::Scene Scene(int64_t end_ns, uint64_t* generation_out = nullptr) const {
    TwinState s;
    {
      std::lock_guard lock(state_mu);
      s = state;
      if (generation_out) *generation_out = generation;
    }
    return sim->StateScene(ToRigState(s), Pulses(end_ns - ExposureNs(), end_ns));
  }

  void Fill(uint8_t* data, int width, int height, sim::SimPixelFormat fmt, int64_t timestamp_ns,
            uint64_t frame_index) {
    const int64_t end_ns = Now();
    FrameStamp stamp;
    const sim::Scene scene = Scene(end_ns, &stamp.generation);
    stamp.exposure_end_ns = end_ns;
    stamp.exposure_start_ns = end_ns - ExposureNs();
    {
      std::lock_guard lock(stamps_mu);
      stamps.emplace_back(timestamp_ns, stamp);
      while (stamps.size() > 256) stamps.pop_front();
    }
    std::lock_guard lock(render_mu);
    // The same scene renders to the same image but for its noise: re-render only on change
    // (boards where they were, the same dots).
    bool same = have_image && scene.boards.size() == last_boards.size() &&
                scene.dots.size() == last_dots.size();
    for (size_t i = 0; same && i < scene.boards.size(); ++i) {
      const geometry::Rigid3d& a = scene.boards[i].cam_from_board;
      const geometry::Rigid3d& b = last_boards[i];
      same = (a.translation - b.translation).norm() < 1e-9 &&
             (a.RotationMatrix() - b.RotationMatrix()).norm() < 1e-12;
    }
    for (size_t i = 0; same && i < scene.dots.size(); ++i)
      same = (scene.dots[i].p_in_cam - last_dots[i].p_in_cam).norm() < 1e-6;  // mm
    if (!same) {
      last_image = sim->RenderScene(scene, frame_index);
      last_dots = scene.dots;
      last_boards.clear();
      for (const auto& board : scene.boards) last_boards.push_back(board.cam_from_board);
      have_image = true;
    }
    sim::PlaceImage(last_image, data, width, height, fmt);
  }

  // MCU time (us) of a twin-clock instant, and back.
  int64_t McuUs(int64_t t_ns) const {
    const double rate = 1.0 + options.sim.hall.mcu_rate_error_ppm * 1e-6;
    return options.sim.hall.mcu_offset_us +
           static_cast<int64_t>(std::llround(static_cast<double>(t_ns - origin_ns) * rate / 1e3));
  }
  int64_t TwinNs(int64_t mcu_us) const {
    const double rate = 1.0 + options.sim.hall.mcu_rate_error_ppm * 1e-6;
    return origin_ns +
           static_cast<int64_t>(std::llround(
               static_cast<double>(mcu_us - options.sim.hall.mcu_offset_us) * 1e3 / rate));
  }

  // Field (uT, sensor axes) at twin-clock instant t_ns, noise-free.
  Eigen::Vector3d FieldAt(int64_t t_ns) const {
    const std::shared_ptr<const Physics> p = CurrentPhysics();
    bool magnet = false;
    {
      std::lock_guard lock(state_mu);
      magnet = state.msm_mounted && state.top_frame_mounted;
    }
    const auto& h = options.sim.hall;
    Eigen::Vector3d b = p->hall->CoilFieldUT(p->GeneratorTimeS(t_ns)) +
                        Eigen::Vector3d(h.earth_uT[0], h.earth_uT[1], h.earth_uT[2]);
    if (magnet)
      b += p->hall->MagnetFieldUT(p->PoseAtNs(t_ns));
    else
      b += Eigen::Vector3d(h.background_shift_uT[0], h.background_shift_uT[1],
                           h.background_shift_uT[2]);
    return b;
  }

  // Rising clock edges (unit 2 ch2 square, output on) in (from_ns, to_ns].
  std::vector<int64_t> ClockEdges(int64_t from_ns, int64_t to_ns) const {
    std::vector<int64_t> out;
    const sim::ChannelSignal c = generators->unit(2).Signal(2);
    if (!Playing(c) || c.function != sim::Function::kSquare || !(c.frequency_hz > 0)) return out;
    const double period_ns = 1e9 / c.frequency_hz;
    const double phase = StartPhaseDeg(c) / 360.0;
    auto edge = [&](int64_t m) {
      return c.start_time_ns +
             static_cast<int64_t>(std::llround((static_cast<double>(m) - phase) * period_ns));
    };
    const auto lo = std::max(from_ns, c.start_time_ns - 1);
    int64_t m = static_cast<int64_t>(
        std::floor(static_cast<double>(lo - c.start_time_ns) / period_ns + phase));
    for (int n = 0; n < 10000; ++n, ++m) {
      const int64_t t = edge(m);
      if (t > to_ns) break;
      if (t > from_ns && t >= c.start_time_ns) out.push_back(t);
    }
    return out;
  }

  void ServeHands();
  void HandleConnection(int fd);
};

// The Hall MCU's view of the world: readings every sample period of MCU time, clock edges as
// they come, computed from the twin's state when the MCU takes them, each handed over when its
// time has come. Readings not taken while the host was not streaming are skipped (the stream
// restarts at the present).
class PhysicalTwin::Impl::HallSource final : public sim::McuDataSource {
 public:
  HallSource(const PhysicalTwin::Impl& twin, uint16_t rate_hz, uint64_t seed)
      : twin_(twin), period_us_(std::max<int64_t>(1, 1000000 / rate_hz)), rng_(seed) {}

  std::optional<sim::McuEvent> Next() override {
    if (!queue_.empty()) return Pop();
    const int64_t now_us = twin_.McuUs(twin_.Now());
    if (next_us_ == 0 || next_us_ < now_us - 50000) {
      next_us_ = (now_us / period_us_ + 1) * period_us_;
      last_us_ = next_us_ - period_us_;
    }
    const int64_t reading_us = next_us_;
    next_us_ += period_us_;
    for (int64_t e : twin_.ClockEdges(twin_.TwinNs(last_us_), twin_.TwinNs(reading_us))) {
      sim::McuEvent ev;
      ev.kind = sim::McuEvent::Kind::kClockEdge;
      ev.time_us = std::max(last_us_ + 1, std::min(reading_us, twin_.McuUs(e)));
      queue_.push_back(ev);
    }
    last_us_ = reading_us;
    // A reading stamped t shows the field delta_t earlier (the sensor's delay).
    const auto delay_ns = static_cast<int64_t>(twin_.options.sim.hall.delta_t_s * 1e9);
    const Eigen::Vector3d b = twin_.FieldAt(twin_.TwinNs(reading_us) - delay_ns);
    const double sigma = twin_.options.sim.hall.noise_uT;
    sim::McuEvent r;
    r.kind = sim::McuEvent::Kind::kField;
    r.time_us = reading_us;
    for (int i = 0; i < 3; ++i) r.field_uT[i] = b[i] + sigma * noise_(rng_);
    queue_.push_back(r);
    return Pop();
  }

 private:
  // The MCU emits an event when its time has come (real time on the twin's clock): the twin
  // paces the stream itself, so that after a pause in streaming it resumes at the present.
  sim::McuEvent Pop() {
    sim::McuEvent e = queue_.front();
    queue_.pop_front();
    const int64_t due_ns = twin_.TwinNs(e.time_us);
    for (int64_t now = twin_.Now(); now < due_ns; now = twin_.Now())
      std::this_thread::sleep_for(
          std::chrono::nanoseconds(std::min<int64_t>(due_ns - now, 2000000)));
    return e;
  }
  const PhysicalTwin::Impl& twin_;
  int64_t period_us_;
  int64_t next_us_ = 0, last_us_ = 0;
  std::deque<sim::McuEvent> queue_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> noise_{0.0, 1.0};
};

void PhysicalTwin::Impl::ServeHands() {
  while (true) {
    pollfd p[2] = {{listen_fd, POLLIN, 0}, {stop_pipe[0], POLLIN, 0}};
    const int r = ::poll(p, 2, -1);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0 || (p[1].revents & POLLIN)) return;
    if (!(p[0].revents & POLLIN)) continue;
    const int fd = ::accept4(listen_fd, nullptr, nullptr, SOCK_CLOEXEC);
    if (fd < 0) continue;
    HandleConnection(fd);
    ::close(fd);
  }
}

void PhysicalTwin::Impl::HandleConnection(int fd) {
  // One request line per connection, read within 5 s.
  std::string line;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (line.find('\n') == std::string::npos && line.size() < (1u << 20)) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                          deadline - std::chrono::steady_clock::now())
                          .count();
    if (left <= 0) return;
    pollfd p[2] = {{fd, POLLIN, 0}, {stop_pipe[0], POLLIN, 0}};
    const int r = ::poll(p, 2, static_cast<int>(left));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0 || (p[1].revents & POLLIN)) return;
    char buf[4096];
    const ssize_t n = ::recv(fd, buf, sizeof(buf), 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    line.append(buf, static_cast<size_t>(n));
  }
  const HandsReply reply = handler(line.substr(0, line.find('\n')));
  const std::string out = FormatHandsReply(reply) + "\n";
  size_t sent = 0;
  while (sent < out.size()) {
    const ssize_t n = ::send(fd, out.data() + sent, out.size() - sent, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    sent += static_cast<size_t>(n);
  }
}

PhysicalTwin::PhysicalTwin(const PhysicalTwinOptions& options) : impl_(std::make_unique<Impl>()) {
  if (std::string e = options.Validate(); !e.empty()) throw std::invalid_argument(e);
  Impl& m = *impl_;
  m.options = options;
  m.clock = options.clock_ns ? options.clock_ns : [] {
    return static_cast<int64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                    std::chrono::steady_clock::now().time_since_epoch())
                                    .count());
  };
  m.origin_ns = m.clock();
  m.sim = std::make_shared<const sim::RigSimulator>(options.sim);
  for (int id = 1; id <= options.sim.beams.count; ++id) m.state.beams_unblocked.push_back(id);
  m.handler = [this](const std::string& line) { return Handle(line); };

  sim::GeneratorPairOptions g;
  g.port1 = options.port1;
  g.port2 = options.port2;
  try {
    m.generators = std::make_unique<sim::MockGeneratorPair>(g, m.clock);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("twin generators: ") + e.what());
  }

  if (!options.camera_address.empty()) {
    sim::MockGvCameraOptions cam;
    cam.address = options.camera_address;
    cam.serial = "MSMCAL-TWIN-1";
    cam.sensor_width = m.sim->camera().width;
    cam.sensor_height = m.sim->camera().height;
    cam.frame_rate_hz = options.camera_frame_rate_hz;
    std::string error;
    Impl* impl = impl_.get();
    m.camera = sim::MockGvCamera::Start(
        cam,
        [impl](uint8_t* data, int width, int height, sim::SimPixelFormat fmt, int64_t timestamp_ns,
               uint64_t frame_index) {
          // On the camera's C thread: nothing may escape. A frame that cannot be rendered is
          // black (and said so once per kind of failure on stderr).
          try {
            impl->Fill(data, width, height, fmt, timestamp_ns, frame_index);
          } catch (const std::exception& e) {
            std::memset(data, 0, static_cast<size_t>(width) * height * sim::SimBytesPerPixel(fmt));
            static std::string last;
            if (last != e.what())
              std::fprintf(stderr, "twin camera: frame not rendered: %s\n", e.what());
            last = e.what();
          }
        },
        &error);
    if (!m.camera)
      throw std::runtime_error("twin camera on " + options.camera_address + ": " + error);
    m.served_camera.store(m.camera.get());
  }

  sim::MockMcuOptions mo;
  mo.link_path = options.hall_link_path;
  mo.speed = 0;  // the source paces itself on the twin's clock (HallSource::Pop)
  mo.rate_hz = options.hall_rate_hz;
  mo.record_sent = false;
  mo.now_ns = m.clock;
  try {
    m.mcu = std::make_unique<sim::MockMcu>(
        mo, std::make_unique<Impl::HallSource>(m, options.hall_rate_hz, options.sim.seed));
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("twin Hall MCU: ") + e.what());
  }
  m.hall_device = m.mcu->device_path();
  m.mcu->Start();

  if (!options.hands_socket.empty()) {
    const std::string& path = options.hands_socket;
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    if (path.size() >= sizeof(addr.sun_path))
      throw std::runtime_error("hands socket " + path + ": path too long for a Unix socket");
    std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
    struct stat st {};
    if (::lstat(path.c_str(), &st) == 0) {
      if (!S_ISSOCK(st.st_mode))
        throw std::runtime_error("hands socket " + path + ": exists and is not a socket");
      ::unlink(path.c_str());  // a stale socket of a previous twin
    }
    m.listen_fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (m.listen_fd < 0 ||
        ::bind(m.listen_fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 ||
        ::listen(m.listen_fd, 8) != 0)
      throw std::runtime_error("hands socket " + path + ": " + std::strerror(errno));
    if (::pipe2(m.stop_pipe, O_CLOEXEC) != 0)
      throw std::runtime_error(std::string("hands socket: pipe: ") + std::strerror(errno));
    m.hands_thread = std::thread([impl = impl_.get()] { impl->ServeHands(); });
  }
  // Last: nothing throws after a thread of ours runs (the destructor joins them).
  m.watch_thread = std::thread([impl = impl_.get()] { impl->Watch(); });
}

PhysicalTwin::~PhysicalTwin() {
  Impl& m = *impl_;
  if (m.watch_thread.joinable()) {
    {
      std::lock_guard lock(m.watch_mu);
      m.watch_stop = true;
    }
    m.watch_cv.notify_all();
    m.watch_thread.join();
  }
  if (m.hands_thread.joinable()) {
    const char c = 'x';
    (void)!::write(m.stop_pipe[1], &c, 1);
    m.hands_thread.join();
  }
  if (m.listen_fd >= 0) {
    ::close(m.listen_fd);
    ::unlink(m.options.hands_socket.c_str());
  }
  for (int fd : m.stop_pipe)
    if (fd >= 0) ::close(fd);
  m.served_camera.store(nullptr);
  m.camera.reset();
  if (m.mcu) m.mcu->Stop();
  m.mcu.reset();
  m.generators.reset();
}

const sim::RigSimulator& PhysicalTwin::sim() const { return *impl_->sim; }
int PhysicalTwin::generator_port(int unit) const { return impl_->generators->port(unit); }
const std::string& PhysicalTwin::hall_device() const { return impl_->hall_device; }
int64_t PhysicalTwin::NowNs() const { return impl_->Now(); }

uint64_t PhysicalTwin::Apply(const TwinSetup& setup) {
  Impl& m = *impl_;
  const int beams = m.options.sim.beams.count;
  if (setup.beams_unblocked)
    for (int id : *setup.beams_unblocked)
      if (id < 1 || id > beams)
        throw std::invalid_argument("beams_unblocked: beam " + std::to_string(id) +
                                    " does not exist (the twin has beams 1.." +
                                    std::to_string(beams) + ")");
  if (setup.camera && *setup.camera != 1 && *setup.camera != 2)
    throw std::invalid_argument("camera: " + std::to_string(*setup.camera) + ": C1 or C2");
  std::lock_guard lock(m.state_mu);
  if (setup.camera) m.state.camera = *setup.camera;
  if (setup.msm_mounted) m.state.msm_mounted = *setup.msm_mounted;
  if (setup.top_frame_mounted) m.state.top_frame_mounted = *setup.top_frame_mounted;
  if (setup.sliding_plate) {
    if (setup.sliding_plate->mounted)
      m.state.sliding_plate = *setup.sliding_plate;
    else
      m.state.sliding_plate.reset();
  }
  if (setup.beams_unblocked) {
    std::vector<int> ids = *setup.beams_unblocked;
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    m.state.beams_unblocked = ids;
  }
  return ++m.generation;
}

TwinState PhysicalTwin::State() const {
  std::lock_guard lock(impl_->state_mu);
  return impl_->state;
}

uint64_t PhysicalTwin::generation() const {
  std::lock_guard lock(impl_->state_mu);
  return impl_->generation;
}

HandsReply PhysicalTwin::Handle(const std::string& line) {
  HandsReply reply;
  try {
    const HandsRequest request = ParseHandsRequest(line);
    if (request.kind == HandsRequest::Kind::kTruthRequest) {
      WriteTruth(request.dir);
      reply.generation = generation();
    } else {
      reply.generation = Apply(request.setup);
    }
    reply.ok = true;
  } catch (const std::exception& e) {
    reply.ok = false;
    reply.error = e.what();
    reply.generation = generation();
  }
  return reply;
}

void PhysicalTwin::WriteTruth(const fs::path& dir) {
  Impl& m = *impl_;
  // The physics now (records it when the drives and the laser are all running).
  (void)m.Pulses(m.Now(), m.Now());
  std::optional<AppliedDrive> drive;
  std::vector<double> times;
  {
    std::lock_guard lock(m.applied_mu);
    drive = m.applied_drive;
    times = m.applied_times;
  }
  if (!drive || times.empty())
    throw std::runtime_error(
        "truth: no drive and trigger table applied yet (both drives and the laser have not "
        "been running together)");
  sim::SimOptions o = m.options.sim;
  o.mirror = drive->mirror;
  // MCU time at generator time 0 on the twin's clock.
  o.hall.mcu_offset_us = m.McuUs(drive->t0_ns);
  const double period = o.PatternPeriodS();
  if (!(period > 0))
    throw std::runtime_error("truth: the applied drives have no common pattern period");
  for (double& t : times) t = std::fmod(t, period);
  std::sort(times.begin(), times.end());
  std::unique_ptr<sim::RigSimulator> truth_sim;
  try {
    truth_sim = std::make_unique<sim::RigSimulator>(o, times);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("truth: the applied drive: ") + e.what());
  }
  const sim::SimTruth truth = sim::MakeTruth(*truth_sim);
  // WriteTruth writes PARENT/truth/: write beside, then move the files into dir.
  fs::create_directories(dir);
  const fs::path staging = dir / (".twin-truth-" + std::to_string(::getpid()));
  fs::remove_all(staging);
  sim::WriteTruth(staging, truth);
  for (const auto& entry : fs::directory_iterator(staging / "truth"))
    fs::rename(entry.path(), dir / entry.path().filename());
  fs::remove_all(staging);
}

AppliedDrive PhysicalTwin::Drive() const { return impl_->CurrentPhysics()->drive; }

std::vector<double> PhysicalTwin::LaserPatternTimesS() const {
  const LaserPattern lp = impl_->CurrentLaser();
  if (!lp.playing) return {};
  return impl_->PatternTimes(lp, impl_->CurrentPhysics()->drive.t0_ns);
}

std::vector<sim::PulseAtPose> PhysicalTwin::PulsesBetween(int64_t from_ns, int64_t to_ns) const {
  return impl_->Pulses(from_ns, to_ns);
}

sim::Scene PhysicalTwin::SceneAt(int64_t end_ns) const { return impl_->Scene(end_ns); }

std::optional<FrameStamp> PhysicalTwin::FrameStampFor(int64_t device_timestamp_ns) const {
  std::lock_guard lock(impl_->stamps_mu);
  for (auto it = impl_->stamps.rbegin(); it != impl_->stamps.rend(); ++it)
    if (it->first == device_timestamp_ns) return it->second;
  return std::nullopt;
}

}  // namespace msmcal::twin
