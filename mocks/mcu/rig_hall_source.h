#pragma once
// McuDataSource over the rig simulator's Hall model (mocks/rig): the field the MCU would read
// during a scan ("actual") or a background recording, with the clock edges, in MCU-time order.
// Kept in its own area library (msmcal_mocks_mcu_rig) so the mock MCU does not depend on the rig.

#include <memory>

#include "mocks/mcu/mcu_source.h"
#include "mocks/rig/hall_model.h"
#include "mocks/rig/sim_options.h"

namespace msmcal::sim {

class RigHallSource final : public McuDataSource {
 public:
  // Owns its HallModel; the stream is deterministic for (options, kind, seed).
  RigHallSource(const SimOptions& options, HallRecordingKind kind, uint64_t seed);
  std::optional<McuEvent> Next() override;

 private:
  std::unique_ptr<HallModel> model_;
  std::unique_ptr<HallSampler> sampler_;
};

}  // namespace msmcal::sim
