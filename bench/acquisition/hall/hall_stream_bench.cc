// Throughput of the Hall MCU host path: decoding + tracking (pure), and the whole pipeline
// mock MCU -> pty -> Boost.Asio driver -> recorder -> sink, as fast as possible.
#include <benchmark/benchmark.h>

#include "acquisition/hall/hall_recorder.h"
#include "drivers/hall_mcu/decoder.h"
#include "mocks/mcu/mock_mcu.h"

namespace msmcal {
namespace {

void BM_DecodeAndTrackReadings(benchmark::State& state) {
  std::vector<uint8_t> bytes;
  for (uint32_t i = 0; i < 10000; ++i) {
    hall_mcu::EncodeFrame({hall_mcu::FrameType::kFieldReading, i, 1000 * int64_t{i},
                           hall_mcu::EncodeField({1, 2, 3, 7, 0, 0, 0})},
                          &bytes);
  }
  for (auto _ : state) {
    hall_mcu::FrameDecoder decoder;
    hall_mcu::StreamTracker tracker;
    hall_mcu::HallBatch batch;
    batch.readings.reserve(10000);
    decoder.Feed(bytes);
    while (auto f = decoder.Next()) tracker.Accept(*f, &batch);
    benchmark::DoNotOptimize(batch.readings.data());
  }
  state.SetItemsProcessed(state.iterations() * 10000);
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(bytes.size()));
}
BENCHMARK(BM_DecodeAndTrackReadings);

void BM_RecordThroughPty(benchmark::State& state) {
  const double seconds = 10;
  for (auto _ : state) {
    sim::SyntheticSourceOptions o;
    o.duration_s = seconds;
    sim::MockMcu mock({}, std::make_unique<sim::SyntheticSource>(o));
    mock.Start();
    hall_mcu::HallMcuOptions d;
    d.device = mock.device_path();
    auto sensor = hall_mcu::OpenHallMcu(d);
    uint64_t n = 0;
    acquisition::HallRecorder recorder(
        *sensor, [&](const hall_mcu::HallBatch& b) { n += b.readings.size(); }, {});
    recorder.Start();
    recorder.Wait();
    if (n != 10000) state.SkipWithError("lost readings");
  }
  state.SetItemsProcessed(state.iterations() * 10000);
}
BENCHMARK(BM_RecordThroughPty)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace msmcal
