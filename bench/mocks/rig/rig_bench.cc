// Rig simulator throughput: Hall sampling (the mock MCU streams it in real time at 1 kHz),
// scene construction (the mock camera asks for one per frame) and a full-resolution frame.
#include <benchmark/benchmark.h>

#include "mocks/rig/hall_model.h"
#include "mocks/rig/rig_simulator.h"

namespace msmcal::sim {
namespace {

const RigSimulator& Sim() {
  static const RigSimulator sim{SimOptions{}};
  return sim;
}

void BM_HallSamplerReadings(benchmark::State& state) {
  HallSampler sampler(Sim().hall(), HallRecordingKind::kActual, 1, /*duration_s=*/0.0);
  for (auto _ : state) benchmark::DoNotOptimize(sampler.Next());
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_HallSamplerReadings);

void BM_Step2ScanScene(benchmark::State& state) {
  const auto& frame = Sim().step2_frames().back();
  for (auto _ : state) benchmark::DoNotOptimize(Sim().FrameScene(frame));
}
BENCHMARK(BM_Step2ScanScene);

void BM_BuildSimulator(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(RigSimulator(SimOptions{}).triggers().size());
}
BENCHMARK(BM_BuildSimulator)->Unit(benchmark::kMillisecond);

void BM_RenderScanFrame5MP(benchmark::State& state) {
  const size_t i = Sim().step2_frames().size() - 1;
  for (auto _ : state) benchmark::DoNotOptimize(Sim().RenderStep2Frame(i));
}
BENCHMARK(BM_RenderScanFrame5MP)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace msmcal::sim
