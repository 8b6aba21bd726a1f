#include "mocks/mcu/rig_hall_source.h"

namespace msmcal::sim {

RigHallSource::RigHallSource(const SimOptions& options, HallRecordingKind kind, uint64_t seed)
    : model_(std::make_unique<HallModel>(options)),
      sampler_(std::make_unique<HallSampler>(*model_, kind, seed)) {}

std::optional<McuEvent> RigHallSource::Next() {
  std::optional<HallEvent> e = sampler_->Next();
  if (!e) return std::nullopt;
  McuEvent out;
  out.time_us = e->mcu_time_us;
  if (e->type == HallEvent::Type::kClockEdge) {
    out.kind = McuEvent::Kind::kClockEdge;
  } else {
    out.kind = McuEvent::Kind::kField;
    out.field_uT = {e->reading.bx_uT, e->reading.by_uT, e->reading.bz_uT};
  }
  return out;
}

}  // namespace msmcal::sim
