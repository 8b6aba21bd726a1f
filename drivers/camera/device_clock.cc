#include "drivers/camera/device_clock.h"

#include <algorithm>
#include <cstdlib>

namespace msmcal::camera {

DeviceClockMap::DeviceClockMap(size_t window, int64_t reset_ns)
    : window_(std::max<size_t>(1, window)), reset_ns_(reset_ns) {}

void DeviceClockMap::Observe(const FrameInfo& info) {
  if (info.device_timestamp_ns == 0) return;
  const int64_t delta = info.host_timestamp_ns - info.device_timestamp_ns;
  if (const std::optional<int64_t> now = OffsetNs(); now && std::llabs(delta - *now) > reset_ns_)
    deltas_.clear();
  deltas_.push_back(delta);
  while (deltas_.size() > window_) deltas_.pop_front();
}

std::optional<int64_t> DeviceClockMap::OffsetNs() const {
  if (deltas_.empty()) return std::nullopt;
  return *std::min_element(deltas_.begin(), deltas_.end());
}

std::optional<int64_t> DeviceClockMap::HostNs(int64_t device_ns) const {
  const std::optional<int64_t> offset = OffsetNs();
  if (!offset) return std::nullopt;
  return device_ns + *offset;
}

}  // namespace msmcal::camera
