#include "sessions/plan/session_plan.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "common/number_format.h"
#include "drivers/generator/rig_generators.h"
#include "processing/plan/frame_design.h"
#include "processing/signal/rig_signals.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::plan {
namespace {

std::string Num(double v) { return common::FormatSignificant(v, 6); }

std::vector<SignalPoint> SignalPoints(const rig::RigFile& rig,
                                      const std::vector<dataset::Trigger>& triggers) {
  std::vector<SignalPoint> p;
  for (const auto& t : triggers)
    p.push_back({signal::SineUnit(rig.generators.signals.fast, t.t_s),
                 signal::SineUnit(rig.generators.signals.slow, t.t_s)});
  return p;
}

std::string Bytes(uint64_t b) {
  char buf[64];
  if (b >= (1ull << 30))
    std::snprintf(buf, sizeof(buf), "%.1f GiB", b / double(1ull << 30));
  else
    std::snprintf(buf, sizeof(buf), "%.0f MiB", b / double(1ull << 20));
  return buf;
}

std::string Duration(double s) {
  char buf[64];
  const int m = static_cast<int>(s / 60);
  std::snprintf(buf, sizeof(buf), "%d min %02d s", m, static_cast<int>(s - 60 * m));
  return buf;
}

}  // namespace

std::vector<setup::PoseGeometry> PoseGeometryOf(const rig::RigFile& rig) {
  std::vector<setup::PoseGeometry> g;
  for (int l = 0; l < rig.sliding_plate.poses; ++l)
    g.push_back({rig.sliding_plate.DistanceMm(l), rig.sliding_plate.TiltDeg(l)});
  return g;
}

dataset::Recording DesignSessionPlan(const rig::RigFile& rig) {
  const gen::RigSignalsConfig& sig = rig.generators.signals;
  dataset::Recording plan;
  plan.camera = rig.camera.model;
  plan.world_board = rig.world_board;
  plan.sliding_board = rig.sliding_board;
  for (int id = 1; id <= rig.beams.count; ++id) {
    const bool held_out =
        std::count(rig.beams.validate_ids.begin(), rig.beams.validate_ids.end(), id);
    plan.beams.push_back(
        {id, held_out ? dataset::BeamRole::kValidate : dataset::BeamRole::kEstimate});
  }
  // Trigger table: the rig's sparse design, the times the arb realises.
  signal::TriggerDesign design;
  try {
    design = signal::DesignTriggers(sig.fast, sig.slow, sig.trigger);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("generators.signals.") + e.what());
  }
  if (design.times_s.size() < 3) {
    throw std::invalid_argument("generators.signals.trigger: the design gives " +
                                std::to_string(design.times_s.size()) +
                                " triggers; a plan needs at least 3 (decrease spacing or "
                                "min_separation)");
  }
  plan.drive.fast = {sig.fast.frequency_hz, sig.fast.amplitude_vpp, sig.fast.phase_deg};
  plan.drive.slow = {sig.slow.frequency_hz, sig.slow.amplitude_vpp, sig.slow.phase_deg};
  plan.drive.pattern_period_s = design.pattern_period_s;
  plan.clock_frequency_hz = 1.0 / design.pattern_period_s;
  for (size_t j = 0; j < design.times_s.size(); ++j)
    plan.triggers.push_back({static_cast<int>(j), design.times_s[j]});

  // Step 1.
  Step1FrameOptions s1;
  s1.poses = rig.sliding_plate.poses;
  s1.beams = rig.beams.count;
  s1.identification_frames = rig.step1.identification_frames;
  s1.background_frames = rig.step1.background_frames;
  s1.exposures = rig.step1.exposures;
  plan.step1 = DesignStep1Frames(s1);

  // Step 2: neutral, fast-only, scan; each `exposures` times in a row.
  std::vector<int> all(rig.beams.count);
  std::iota(all.begin(), all.end(), 1);
  const rig::Step2Design& d2 = rig.step2;
  const std::vector<SignalPoint> points = SignalPoints(rig, plan.triggers);
  std::vector<dataset::Step2Frame> frames;
  for (int i = 0; i < d2.neutral_frames; ++i)
    frames.push_back({"", dataset::Step2Kind::kNeutral, {}, all});
  for (const auto& g : ChooseFastOnlyGroups(
           points, d2.fast_only_frames, d2.fast_only_triggers_per_frame, d2.frame_min_separation))
    frames.push_back({"", dataset::Step2Kind::kFastOnly, g, all});
  for (const auto& g :
       GroupBySeparation(points, d2.scan_triggers_per_frame, d2.frame_min_separation))
    frames.push_back({"", dataset::Step2Kind::kScan, g, all});
  for (const auto& f : frames) {
    for (int k = 0; k < d2.exposures; ++k) {
      dataset::Step2Frame copy = f;
      copy.file = FrameFile("step2", plan.step2.size());
      plan.step2.push_back(copy);
    }
  }
  if (std::string e = interchange::CheckRecording(plan); !e.empty())
    throw std::invalid_argument("plan: " + e);
  return plan;
}

std::string CheckPlanAgainstRig(const dataset::Recording& plan, const rig::RigFile& rig) {
  const gen::RigSignalsConfig& sig = rig.generators.signals;
  std::ostringstream os;
  auto axis = [&](const char* name, const dataset::DriveAxis& a, const signal::SineDrive& s) {
    if (a.frequency_hz != s.frequency_hz || a.amplitude_vpp != s.amplitude_vpp ||
        a.phase_deg != s.phase_deg) {
      os << "plan drive." << name << " = {frequency_hz: " << Num(a.frequency_hz)
         << ", amplitude_vpp: " << Num(a.amplitude_vpp) << ", phase_deg: " << Num(a.phase_deg)
         << "}: differs from the rig file's generators.signals.drive." << name
         << " {frequency_hz: " << Num(s.frequency_hz) << ", amplitude_vpp: " << Num(s.amplitude_vpp)
         << ", phase_deg: " << Num(s.phase_deg)
         << "} (the generators play the rig file's drive; re-plan with `msmcal plan`)";
      return false;
    }
    return true;
  };
  // The plan's drive through the mirror's limits first (a plan edited by hand names the limit).
  gen::RigGeneratorConfig with_plan = rig.generators;
  with_plan.signals.fast.frequency_hz = plan.drive.fast.frequency_hz;
  with_plan.signals.fast.amplitude_vpp = plan.drive.fast.amplitude_vpp;
  with_plan.signals.fast.phase_deg = plan.drive.fast.phase_deg;
  with_plan.signals.slow.frequency_hz = plan.drive.slow.frequency_hz;
  with_plan.signals.slow.amplitude_vpp = plan.drive.slow.amplitude_vpp;
  with_plan.signals.slow.phase_deg = plan.drive.slow.phase_deg;
  if (std::string e = with_plan.Validate(); !e.empty()) return "plan drive: " + e;
  if (!axis("fast", plan.drive.fast, sig.fast) || !axis("slow", plan.drive.slow, sig.slow))
    return os.str();
  if (plan.camera.width != rig.camera.model.width ||
      plan.camera.height != rig.camera.model.height) {
    os << "plan camera.yaml image_size = [" << plan.camera.width << ", " << plan.camera.height
       << "]: differs from the rig file's camera [" << rig.camera.model.width << ", "
       << rig.camera.model.height << "]";
    return os.str();
  }
  for (const auto& b : plan.beams) {
    if (b.id < 1 || b.id > rig.beams.count) {
      os << "plan beams id = " << b.id << ": outside the rig's beams 1.." << rig.beams.count;
      return os.str();
    }
  }
  const signal::TriggerDesignOptions& t = sig.trigger;
  if (static_cast<int>(plan.triggers.size()) > t.max_triggers) {
    os << "plan triggers: " << plan.triggers.size()
       << " triggers exceed generators.signals.trigger.max_triggers = " << t.max_triggers;
    return os.str();
  }
  try {
    (void)gen::PlanRigSignals(sig);
  } catch (const std::invalid_argument& e) {
    return std::string("generators.signals: ") + e.what();
  }
  // Duty of the plan's own table with the rig's pulse width.
  const double period = plan.drive.pattern_period_s;
  const double duty = plan.triggers.size() * t.pulse_width_s / period;
  if (duty > t.max_duty) {
    os << "plan triggers: duty = " << Num(duty) << " (" << plan.triggers.size() << " pulses of "
       << Num(t.pulse_width_s) << " s in " << Num(period)
       << " s) exceeds generators.signals.trigger.max_duty = " << Num(t.max_duty);
    return os.str();
  }
  for (const auto& tr : plan.triggers) {
    if (!(tr.t_s >= 0 && tr.t_s < period)) {
      os << "plan triggers j = " << tr.j << ": t_s = " << Num(tr.t_s)
         << " outside the pattern period [0, " << Num(period) << ")";
      return os.str();
    }
  }
  return {};
}

PlanSummary SummarisePlan(const dataset::Recording& plan, const rig::RigFile& rig) {
  PlanSummary s;
  s.step1_frames = plan.step1.size();
  s.step2_frames = plan.step2.size();
  s.triggers = plan.triggers.size();
  const setup::SetupPlan setups = setup::PlanSetups(plan, PoseGeometryOf(rig));
  s.setups = static_cast<int>(setups.setups.size());
  const double frame_s = 2.0 / rig.camera.frame_rate_hz + 0.3;  // stale + fresh + settle
  const size_t frames = s.step1_frames + s.step2_frames;
  const double step2_s = std::max(rig.step2.hall_actual_min_s, s.step2_frames * frame_s);
  s.expected_duration_s = s.setups * kSecondsPerChange + s.step1_frames * frame_s +
                          rig.step2.hall_background_s + step2_s;
  const uint64_t image = static_cast<uint64_t>(plan.camera.width) * plan.camera.height;
  const double hall_s = rig.step2.hall_background_s + step2_s + s.setups * kSecondsPerChange;
  const uint64_t hall = static_cast<uint64_t>(hall_s * rig.hall_mcu.rate_hz * 40.0);
  s.disk_bytes = 2 * (frames * image + hall);
  std::ostringstream t;
  t << "frames: " << s.step1_frames << " step 1, " << s.step2_frames << " step 2 (" << s.triggers
    << " triggers)\n"
    << "prompts: " << s.setups << " set-ups a person (or a hook) is asked for\n"
    << "expected duration: about " << Duration(s.expected_duration_s) << " ("
    << Num(kSecondsPerChange) << " s per set-up change)\n"
    << "disk needed: about " << Bytes(s.disk_bytes) << "\n";
  s.text = t.str();
  return s;
}

void WritePlanFolder(const std::filesystem::path& dir, const dataset::Recording& plan) {
  std::filesystem::create_directories(dir);
  interchange::WriteFileAtomically(dir / "session.yaml", interchange::FormatSessionYaml(plan));
  interchange::WriteFileAtomically(dir / "camera.yaml", interchange::FormatCameraYaml(plan.camera));
  // Read back: what `session run --plan` will read.
  dataset::Recording back;
  interchange::ParseSessionYaml(interchange::FormatSessionYaml(plan), "session.yaml", &back);
  (void)interchange::ReadCameraYaml(dir / "camera.yaml");
}

}  // namespace msmcal::plan
