// The option set of a rig sweep (`msmcal sweep PLAN --rig RIG`): the rig file's fields. The sweep
// command's defaults are its --rig file; `msmcal report DIR` reads a rig sweep folder's stored
// plan with that plan's base: (every rig file field) as the defaults.
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "sessions/sweep/sweep_plan.h"

namespace msmcal::app {

// A rig sweep's options: the rig file's fields (docs/lab-path.md, "Rig sweeps"). An axis names a
// numeric field by its dotted path (generators.signals.drive.fast.frequency_hz,
// generators.signals.trigger.spacing, step2.scan_triggers_per_frame, ...). A point resolves only
// when its rig file passes every check a session makes before touching the rig: the rig file's
// validation (channel limits: frequency window, Vpp, offset), the plan's design (trigger design:
// duty, point count, sample rate, at least 3 triggers) and the plan against the rig
// (CheckPlanAgainstRig).
class RigSweepParameters : public sweep::SweepParameters {
 public:
  // `defaults_yaml`: a rig file's text; `origin` names it in messages (the rig file's path).
  RigSweepParameters(const std::string& defaults_yaml, std::string origin);
  // The defaults are the rig file `rig_file` (throws std::runtime_error naming it).
  static std::shared_ptr<const RigSweepParameters> FromRigFile(
      const std::filesystem::path& rig_file);

  std::string Noun() const override;
  std::string PathHint() const override;
  std::string DefaultsYaml() const override { return defaults_; }
  std::string LoadFile(const std::filesystem::path& file) const override;
  std::string Resolve(const std::string& yaml, const std::string& where, int repeat,
                      uint64_t* seed) const override;

 private:
  std::string origin_;
  std::string defaults_;
};

// True when a sweep folder's stored plan (DIR/sweep.yaml, as the sweep wrote it) is a rig
// sweep's: its base: holds a rig file's `generators:` (a simulated sweep's holds simulator
// options, which have none). Throws std::runtime_error naming the file when it cannot be read or
// is not YAML (with the line).
bool IsRigSweepPlan(const std::filesystem::path& plan_file);

// A sweep folder's stored plan, read once: a rig sweep's with its own base: as the rig file's
// options (no --rig needed: `msmcal report DIR`), or a simulated sweep's.
struct StoredSweepPlan {
  bool rig = false;
  sweep::SweepPlan plan;
};
// Throws std::runtime_error naming the file: cannot be read, YAML syntax (with the line), or
// the plan's own errors (ParseSweepPlan).
StoredSweepPlan LoadStoredSweepPlan(const std::filesystem::path& plan_file);

}  // namespace msmcal::app
