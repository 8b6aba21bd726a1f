#include "simulation/twin/demo_rig.h"

#include <stdexcept>
#include <utility>

#include "common/check.h"
#include "mocks/generator/mock_server.h"

namespace msmcal::twin {

std::string DemoRigOptions::Validate() const {
  if (camera_address.empty()) return "DemoRigOptions.camera_address is empty";
  if (!(camera_frame_rate_hz > 0))
    return "DemoRigOptions.camera_frame_rate_hz = " + std::to_string(camera_frame_rate_hz) +
           ": must be > 0";
  if (std::string e = sim.Validate(); !e.empty()) return "DemoRigOptions.sim: " + e;
  if ((external_generator_port1 > 0) != (external_generator_port2 > 0) ||
      external_generator_port1 < 0 || external_generator_port2 < 0 ||
      external_generator_port1 > 65535 || external_generator_port2 > 65535)
    return "DemoRigOptions.external_generator_port1/2 = " +
           std::to_string(external_generator_port1) + "/" +
           std::to_string(external_generator_port2) + ": both 1..65535, or both 0";
  return {};
}

DemoRig::DemoRig(const DemoRigOptions& options) : options_(options) {
  if (std::string e = options.Validate(); !e.empty()) throw std::invalid_argument(e);
  sim_ = std::make_shared<const sim::RigSimulator>(options.sim);
  mcus_ = std::make_unique<DemoMcus>();
  world_ = std::make_unique<SimulatedWorld>(sim_, [this](orchestrator::HallRun run) {
    // The background MCU started for the rig check (MakeOrchestratorOptions) is handed out once.
    if (run == orchestrator::HallRun::kBackground && !background_device_.empty())
      return std::exchange(background_device_, std::string());
    return mcus_->Start(options_.sim, run,
                        run == orchestrator::HallRun::kBackground ? options_.background_mcu_faults
                                                                  : options_.actual_mcu_faults);
  });
  if (options.external_generator_port1 == 0)
    generators_ = std::make_unique<sim::MockGeneratorPair>(sim::GeneratorPairOptions{});
  sim::MockGvCameraOptions cam;
  cam.address = options.camera_address;
  cam.sensor_width = sim_->camera().width;
  cam.sensor_height = sim_->camera().height;
  cam.frame_rate_hz = options.camera_frame_rate_hz;
  cam.lost_after_frames = options.camera_lost_after_frames;
  std::string error;
  camera_ = sim::MockGvCamera::Start(cam, world_->MakeFrameSource(), &error);
  if (!camera_) throw std::runtime_error("mock camera on " + options.camera_address + ": " + error);
}

DemoRig::~DemoRig() {
  camera_.reset();
  mcus_.reset();
}

int DemoRig::generators_port(int unit) const {
  if (!generators_)
    return unit == 1 ? options_.external_generator_port1 : options_.external_generator_port2;
  return generators_->port(unit);
}

sim::MockGeneratorPair& DemoRig::generators() {
  MSMCAL_CHECK(generators_)
      << "DemoRig::generators(): the generators are served by another process";
  return *generators_;
}

namespace {

// The demo rig's rig file (generators: section): the mock units on loopback and the limits of
// the simulated mirror's coils, fixed like a lab's config/rig.yaml. A session asks for its drives
// (the simulator's mirror options, a sweep point); the limits never follow the request, so a
// request outside them is refused by the same checks as on the real rig.
constexpr const char* kDemoRigYaml = R"(generators:
  unit1:
    host: 127.0.0.1
    port: 1
    channels:
      1: {role: fast_coil, max_vpp: 4.0, max_abs_offset_v: 0.5,
          min_frequency_hz: 100, max_frequency_hz: 400}  # around the simulated resonance, 210 Hz
      2: {role: slow_coil, max_vpp: 8.0, max_abs_offset_v: 0.5,
          min_frequency_hz: 0.5, max_frequency_hz: 50}
  unit2:
    host: 127.0.0.1
    port: 1
    channels:
      1: {role: laser_trigger, max_vpp: 5.0, max_abs_offset_v: 2.5,
          min_frequency_hz: 0.01, max_frequency_hz: 1000, max_duty: 0.01}
      2: {role: mcu_clock, max_vpp: 3.3, max_abs_offset_v: 1.65,
          min_frequency_hz: 0.01, max_frequency_hz: 1000}
  signals:
    drive:
      fast: {frequency_hz: 205, amplitude_vpp: 2}
      slow: {frequency_hz: 5, amplitude_vpp: 4}
      load_ohm: 50
    laser: {low_v: 0.0, high_v: 5.0, load_ohm: inf}
    clock: {low_v: 0.0, high_v: 3.3, load_ohm: inf}
    trigger: {}
)";

}  // namespace

gen::RigGeneratorConfig DemoGeneratorConfig(const sim::SimOptions& sim, int port1, int port2) {
  gen::RigGeneratorConfig c = gen::ParseRigGeneratorConfig(kDemoRigYaml, "demo rig file");
  const auto& m = sim.mirror;
  c.unit1.name = "generator1";
  c.unit1.link.port = port1;
  c.unit2.name = "generator2";
  c.unit2.link.port = port2;
  // The request: the simulated session's drives.
  c.signals.fast = {m.fast.frequency_hz, m.fast.amplitude_vpp, 0.0, m.fast.phase_deg};
  c.signals.slow = {m.slow.frequency_hz, m.slow.amplitude_vpp, 0.0, m.slow.phase_deg};
  return c;
}

gen::RigGeneratorConfig DemoRig::GeneratorConfig() const {
  return DemoGeneratorConfig(options_.sim, generators_port(1), generators_port(2));
}

orchestrator::OrchestratorOptions DemoRig::MakeOrchestratorOptions(
    const std::filesystem::path& out_dir) const {
  orchestrator::OrchestratorOptions o;
  o.out_dir = out_dir;
  o.generators = GeneratorConfig();
  o.camera = options_.camera_address;
  o.camera_frame_rate_hz = options_.camera_frame_rate_hz;
  o.mcu.stall_timeout_ms = 2000;
  // The rig check identifies the background recording's MCU, which the operator action hands
  // out again when the background recording is due (so the guided operator is told to set it
  // up at the right time).
  if (background_device_.empty())
    background_device_ = mcus_->Start(options_.sim, orchestrator::HallRun::kBackground,
                                      options_.background_mcu_faults);
  o.mcu.device = background_device_;
  o.background_seconds = 0;  // the mock MCU ends with the simulator's recording
  // The actual recording as long as the simulator's, also when step 2 is quick (a resume that
  // finds every step 2 frame recorded); the mock MCU ends it there.
  o.actual_min_seconds = options_.sim.hall.actual_duration_s;
  o.mcu_rate_hz = static_cast<uint16_t>(options_.sim.hall.sample_rate_hz);
  return o;
}

dataset::Recording DemoRig::Plan() const { return sim_->MakeRecording(/*with_hall=*/false); }

}  // namespace msmcal::twin
