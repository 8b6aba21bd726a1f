// MLE scaling with the number of mirror planes (Schur elimination of the planes should make it
// near-linear): 100, 1,000, 10,000 planes of the synthetic scene, solve + covariance.
#include <benchmark/benchmark.h>

#include "processing/solver/initialise.h"
#include "processing/solver/mle.h"
#include "processing/solver/synthetic_scene.h"

namespace {

void BM_SolveMle(benchmark::State& state) {
  msmcal::solver::SyntheticSceneOptions o;
  o.num_planes = static_cast<int>(state.range(0));
  o.seed = 5;
  const auto scene = msmcal::solver::MakeSyntheticScene(o);
  std::string err;
  const auto init = msmcal::solver::InitialEstimate(scene.obs, &err);
  if (!init) {
    state.SkipWithError(err.c_str());
    return;
  }
  msmcal::solver::MleOptions mo;
  mo.estimate_variance_factors = false;
  for (auto _ : state) {
    const auto r = msmcal::solver::SolveMle(scene.obs, *init, mo);
    benchmark::DoNotOptimize(r.plane_cov.data());
    state.counters["ceres_s"] = r.solver_time_s;
    state.counters["iterations"] = r.iterations;
  }
  state.SetComplexityN(state.range(0));
}
BENCHMARK(BM_SolveMle)
    ->Arg(100)
    ->Arg(1000)
    ->Arg(10000)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->Complexity(benchmark::oN);

}  // namespace
