// Readings per second of the live Hall predictor (background subtraction by phase + model), one
// core. Target: tens of millions per second.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "processing/hall/calibration.h"

namespace msmcal::hall {
namespace {

HallPredictor MakePredictor(HallModelKind kind) {
  HallModel m;
  m.kind = kind;
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g;
  m.a = Eigen::MatrixXd(3, m.FeatureCount());
  for (int i = 0; i < m.a.size(); ++i) m.a.data()[i] = g(rng);
  m.field_scale_uT = 300;
  m.sine_frequency_hz = Eigen::Vector3d(86, 4, 86);
  m.delta_t_s = 6e-4;
  std::vector<Eigen::Vector3d> bins(5000);
  for (size_t i = 0; i < bins.size(); ++i) bins[i] = Eigen::Vector3d(std::sin(i * 0.01), std::cos(i * 0.02), 0.1 * i);
  return HallPredictor(m, PhaseProfile::FromBins(0.5, bins), Eigen::Vector3d(10, 20, 30));
}

void BM_PredictBatch(benchmark::State& state) {
  const HallPredictor p = MakePredictor(static_cast<HallModelKind>(state.range(0)));
  const size_t n = 1 << 16;
  std::vector<double> t(n);
  std::vector<Eigen::Vector3d> raw(n), pose(n);
  for (size_t i = 0; i < n; ++i) {
    t[i] = i * 1e-3;
    raw[i] = Eigen::Vector3d(100 + i % 7, -50, 300);
  }
  for (auto _ : state) {
    p.PredictBatch(t.data(), raw.data(), pose.data(), n);
    benchmark::DoNotOptimize(pose.data());
  }
  state.SetItemsProcessed(state.iterations() * n);
  state.SetLabel(ToString(p.model().kind));
}
BENCHMARK(BM_PredictBatch)->Arg(0)->Arg(1)->Arg(2)->Arg(3);

}  // namespace
}  // namespace msmcal::hall
