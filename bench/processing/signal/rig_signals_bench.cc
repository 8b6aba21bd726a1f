// Trigger design cost: one walk over the arb sample grid (up to max_points samples).
#include <benchmark/benchmark.h>

#include "processing/signal/rig_signals.h"

namespace {

void BM_DesignTriggers(benchmark::State& state) {
  const msmcal::signal::SineDrive fast{1230.0, 2.0, 0.0, 0.0};
  const msmcal::signal::SineDrive slow{30.0, 1.5, 0.0, 0.0};
  msmcal::signal::TriggerDesignOptions o;
  o.max_points = state.range(0);
  for (auto _ : state) {
    benchmark::DoNotOptimize(msmcal::signal::DesignTriggers(fast, slow, o));
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_DesignTriggers)->Arg(100'000)->Arg(1'000'000)->Unit(benchmark::kMillisecond);

}  // namespace
