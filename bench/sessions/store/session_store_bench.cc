// Insert rates of the session store: Hall readings in batches (a 1 kHz stream must keep up
// with margin), events one by one. Run by hand: build-*/bench/sessions/store/session_store_bench
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>

#include "sessions/store/session_store.h"

namespace msmcal::store {
namespace {

namespace fs = std::filesystem;

fs::path FreshDir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("msmcal_store_bench_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

// items/s = Hall readings per second, one transaction (commit + WAL fsync) per batch.
void BM_AppendHallReadings(benchmark::State& state) {
  const fs::path dir = FreshDir("hall");
  const FakeClock clock;
  auto store = SessionStore::Create(dir, SessionMetadata{}, clock);
  std::vector<dataset::HallReading> batch(static_cast<size_t>(state.range(0)));
  int64_t t = 0;
  for (auto _ : state) {
    for (auto& r : batch) r = {static_cast<double>(t += 1000), 12.5, -3.25, 40.0625};
    store->AppendHallReadings("actual", batch);
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
  store.reset();
  fs::remove_all(dir);
}
BENCHMARK(BM_AppendHallReadings)->Arg(1)->Arg(10)->Arg(100)->Arg(1000)->UseRealTime();

void BM_AddEvent(benchmark::State& state) {
  const fs::path dir = FreshDir("events");
  const FakeClock clock;
  auto store = SessionStore::Create(dir, SessionMetadata{}, clock);
  for (auto _ : state) store->AddEvent("info", "frame captured", 0.125);
  state.SetItemsProcessed(state.iterations());
  store.reset();
  fs::remove_all(dir);
}
BENCHMARK(BM_AddEvent)->UseRealTime();

}  // namespace
}  // namespace msmcal::store
