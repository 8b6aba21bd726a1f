#include "simulation/replay/replay_rig.h"

#include <fstream>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "mocks/generator/mock_server.h"
#include "mocks/mcu/mcu_source.h"
#include "mocks/mcu/mock_mcu.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::replay {

namespace fs = std::filesystem;

namespace {

struct HallFiles {
  fs::path readings, clock;
};

HallFiles RecordedHall(const fs::path& source, orchestrator::HallRun run) {
  const std::string name = orchestrator::ToString(run);
  return {source / "hall" / (name + ".csv"), source / "hall" / (name + "_clock.csv")};
}

}  // namespace

// One mock MCU per recording, each replaying the recorded file (started on demand).
struct ReplayRig::Mcus {
  std::vector<std::unique_ptr<sim::MockMcu>> running;
  ~Mcus() {
    for (auto& m : running) m->Stop();
  }
  std::string Start(const fs::path& source, orchestrator::HallRun run, const RigSetup& setup) {
    const HallFiles f = RecordedHall(source, run);
    dataset::HallRecording recording = interchange::ReadHallCsv(f.readings, f.clock);
    sim::MockMcuOptions mo;
    mo.speed = 0;  // as fast as the host reads
    mo.record_sent = false;
    mo.rate_hz = setup.mcu_rate_hz;
    mo.settings = setup.mcu_sensor;
    auto mcu = std::make_unique<sim::MockMcu>(
        mo, std::make_unique<sim::ReplaySource>(std::move(recording)));
    mcu->Start();
    std::string path = mcu->device_path();
    running.push_back(std::move(mcu));
    return path;
  }
};

std::string ReplayRigOptions::Validate() const {
  if (source.empty())
    return "ReplayRigOptions.source is empty: a recorded session folder is needed";
  if (camera_address.empty()) return "ReplayRigOptions.camera_address is empty";
  if (!(camera_frame_rate_hz > 0))
    return "ReplayRigOptions.camera_frame_rate_hz = " + std::to_string(camera_frame_rate_hz) +
           ": must be > 0";
  return {};
}

ReplayRig::ReplayRig(const ReplayRigOptions& options) : options_(options) {
  if (std::string e = options.Validate(); !e.empty()) throw std::invalid_argument(e);
  if (!fs::is_directory(options.source))
    throw std::runtime_error(options.source.string() + ": no such session folder");
  options_.source = fs::absolute(options.source).lexically_normal();
  const fs::path& src = options_.source;
  source_run_ = ReadSourceRun(src);
  const orchestrator::SessionJournalState journal = orchestrator::ReadSessionJournal(src);
  rig_id_ = journal.rig_id;
  mirror_id_ = journal.mirror_id;
  setup_ = SetupFromSourceRun(source_run_);
  plan_ = orchestrator::LoadSessionPlan(src);
  for (auto run : {orchestrator::HallRun::kBackground, orchestrator::HallRun::kActual}) {
    const HallFiles f = RecordedHall(src, run);
    for (const fs::path& p : {f.readings, f.clock})
      if (!fs::is_regular_file(p))
        throw std::runtime_error(p.string() + ": recorded Hall file missing: cannot replay the " +
                                 orchestrator::ToString(run) + " recording");
  }
  mcus_ = std::make_unique<Mcus>();
  world_ = std::make_unique<ReplayWorld>(src, plan_, [this](orchestrator::HallRun run) {
    return mcus_->Start(options_.source, run, setup_);
  });
  // The mocks answer *IDN? / *OPT? as the recorded instruments did (a lab session's real units).
  sim::GeneratorPairOptions pair;
  if (std::ifstream in(src / "generators_transcript.txt", std::ios::binary); in) {
    std::stringstream text;
    text << in.rdbuf();
    for (auto [unit, options] :
         {std::pair{"unit1", &pair.unit1}, std::pair{"unit2", &pair.unit2}}) {
      const RecordedIdentity id = IdentityFromTranscript(text.str(), unit);
      if (!id.identity.empty()) options->identity = id.identity;
      if (!id.options_reply.empty()) options->options_reply = id.options_reply;
    }
  }
  generators_ = std::make_unique<sim::MockGeneratorPair>(pair);
  sim::MockGvCameraOptions cam;
  cam.address = options.camera_address;
  cam.sensor_width = plan_.camera.width;
  cam.sensor_height = plan_.camera.height;
  cam.frame_rate_hz = options.camera_frame_rate_hz;
  std::string error;
  camera_ = sim::MockGvCamera::Start(cam, world_->MakeFrameSource(), &error);
  if (!camera_) throw std::runtime_error("mock camera on " + options.camera_address + ": " + error);
}

ReplayRig::~ReplayRig() {
  camera_.reset();  // stops calling the world's frame source
  mcus_.reset();
}

int ReplayRig::generators_port(int unit) const { return generators_->port(unit); }

gen::RigGeneratorConfig ReplayRig::GeneratorConfig() const {
  gen::RigGeneratorConfig c = setup_.generators;
  c.unit1.link.host = "127.0.0.1";
  c.unit1.link.port = generators_->port(1);
  c.unit2.link.host = "127.0.0.1";
  c.unit2.link.port = generators_->port(2);
  return c;
}

orchestrator::OrchestratorOptions ReplayRig::MakeOrchestratorOptions(
    const fs::path& out_dir) const {
  orchestrator::OrchestratorOptions o;
  o.out_dir = out_dir;
  o.generators = GeneratorConfig();
  o.camera = options_.camera_address;
  o.camera_frame_rate_hz = options_.camera_frame_rate_hz;
  o.mcu = setup_.mcu;
  o.mcu.device.clear();      // RunSession asks the world for the background MCU (a replaying mock)
  o.background_seconds = 0;  // the replayed background recording ends with its data
  o.actual_min_seconds = 86400;  // the replayed actual recording too, however quick step 2 is
  o.mcu_rate_hz = setup_.mcu_rate_hz;
  o.run_kind = "replay";
  o.run_config_yaml = ReplayRunConfigYaml(options_.source, source_run_);
  o.rig_id = rig_id_;
  o.mirror_id = mirror_id_;
  o.note = "msmcal replay of " + options_.source.string();
  return o;
}

}  // namespace msmcal::replay
