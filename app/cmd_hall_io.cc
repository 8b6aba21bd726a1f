// `msmcal mock mcu`: a mock Hall MCU on a pseudo-terminal (docs/protocols/hall-mcu.md).
// `msmcal hall record`: records readings and clock edges from a Hall MCU into interchange CSVs.
#include <pthread.h>
#include <signal.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "acquisition/hall/hall_csv_writer.h"
#include "acquisition/hall/hall_recorder.h"
#include "app/command_registry.h"
#include "drivers/hall_mcu/hall_mcu_config.h"
#include "drivers/hall_mcu/hall_sensor.h"
#include "mocks/mcu/mock_mcu.h"
#include "mocks/mcu/rig_hall_source.h"
#include "mocks/rig/sim_options.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;

struct MockArgs {
  std::string link;
  std::string mode = "scan";
  double speed = 1.0;
  double seconds = 0;
  uint64_t seed = 1;
  std::string replay;
  std::string source = "rig";
  std::string sim_config;
  bool stream_on_open = false;
  std::vector<std::string> faults;
};

void RunMockMcu(const MockArgs& args) {
  std::unique_ptr<sim::McuDataSource> source;
  if (!args.replay.empty()) {
    const fs::path csv = args.replay;
    source = std::make_unique<sim::ReplaySource>(
        interchange::ReadHallCsv(csv, acquisition::ClockCsvPathFor(csv)));
  } else if (args.source == "rig" && args.mode != "marg") {
    sim::SimOptions sim;
    if (!args.sim_config.empty()) sim = sim::LoadSimOptions(args.sim_config);
    const bool scan = args.mode == "scan";
    if (args.seconds > 0) {
      (scan ? sim.hall.actual_duration_s : sim.hall.background_duration_s) = args.seconds;
    }
    source = std::make_unique<sim::RigHallSource>(
        sim, scan ? sim::HallRecordingKind::kActual : sim::HallRecordingKind::kBackground,
        args.seed);
  } else {
    sim::SyntheticSourceOptions o;
    o.mode = sim::ParseSyntheticMode(args.mode);
    o.duration_s = args.seconds;
    o.seed = args.seed;
    source = std::make_unique<sim::SyntheticSource>(o);
  }
  sim::MockMcuOptions options;
  options.link_path = args.link;
  options.speed = args.speed;
  options.stream_on_open = args.stream_on_open;
  options.seed = args.seed;
  if (args.mode == "marg" && args.replay.empty()) {
    options.identify.sensor_type = hall_mcu::SensorType::kMarg;
  }
  for (const std::string& f : args.faults) options.faults.push_back(sim::ParseMcuFault(f));

  // Block the stop signals before any thread starts, then wait for one of them here.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  sim::MockMcu mock(options, std::move(source));
  mock.Start();
  std::printf("ready %s\n", args.link.c_str());
  std::fflush(stdout);
  spdlog::info("mock mcu: {} -> {}, mode {}, speed {}", args.link, mock.device_path(),
               args.replay.empty() ? args.source + " " + args.mode : "replay " + args.replay,
               args.speed);
  int signal_number = 0;
  sigwait(&stop_signals, &signal_number);
  mock.Stop();
  const sim::MockMcuLog log = mock.Log();
  spdlog::info(
      "mock mcu: stopped by signal {}; sent {} readings, {} clock edges, {} MARG; injected {} "
      "flipped bits, {} dropped bytes, {} resets, {} stalls",
      signal_number, log.readings_sent_total, log.sent_edges.size(), log.sent_marg,
      log.flipped_bits, log.dropped_bytes, log.resets, log.stalls);
}

std::atomic<bool> g_record_interrupted{false};
void OnRecordSignal(int) { g_record_interrupted = true; }

struct RecordArgs {
  std::string rig;
  std::string device;
  double seconds = 0;
  std::string out;
  unsigned baud = 0;
  int rate_hz = 0;
  int gain_sel = -1;
  int res_xy = 0;
  int res_z = 0;
  int stall_timeout_ms = 0;
};

std::string FormatCounts(const acquisition::HallRecorderCounts& c) {
  const hall_mcu::HallCounters& d = c.driver;
  return fmt::format(
      "readings {} (lost {}), clock edges {} (lost {}), marg {}, crc errors {}, bad headers {}, "
      "bytes discarded {}, resets {}, stalls {}, queue drops {}, {:.3f} s",
      d.readings, d.readings_lost, d.clock_edges, d.clock_edges_lost, d.marg_readings, d.crc_errors,
      d.bad_headers, d.bytes_discarded, d.resets, d.stalls, c.readings_dropped, c.seconds_recorded);
}

void RunHallRecord(const RecordArgs& args) {
  // A recording is never overwritten (the writer truncates): checked before the MCU is opened.
  for (const std::filesystem::path& f :
       {std::filesystem::path(args.out), acquisition::ClockCsvPathFor(args.out)})
    if (std::filesystem::exists(f))
      throw std::runtime_error("--out " + args.out + ": " + f.string() +
                               " exists (hall record does not overwrite a recording: choose "
                               "another name or move it away)");
  // The rig configuration's hall_mcu section first, then the flags given on the command line.
  hall_mcu::HallMcuOptions driver_options;
  acquisition::HallRecorderOptions options;
  if (!args.rig.empty()) {
    const hall_mcu::HallMcuConfig config = hall_mcu::LoadHallMcuConfig(args.rig);
    driver_options = config.link;
    options.rate_hz = config.rate_hz;
    options.settings = config.sensor;
  } else if (args.device.empty()) {
    throw std::runtime_error("hall record: give --device or --rig (a rig.yaml with hall_mcu:)");
  }
  if (!args.device.empty()) driver_options.device = args.device;
  if (args.baud > 0) driver_options.baud_rate = args.baud;
  if (args.stall_timeout_ms > 0) driver_options.stall_timeout_ms = args.stall_timeout_ms;
  options.max_seconds = args.seconds;
  if (args.rate_hz > 0) options.rate_hz = static_cast<uint16_t>(args.rate_hz);
  if (args.gain_sel >= 0) {
    hall_mcu::SensorSettings s;
    s.gain_sel = static_cast<uint8_t>(args.gain_sel);
    s.res_x = s.res_y = static_cast<uint8_t>(args.res_xy);
    s.res_z = static_cast<uint8_t>(args.res_z);
    options.settings = s;
  }
  if (std::string msg = options.Validate(); !msg.empty()) throw std::runtime_error(msg);

  auto sensor = hall_mcu::OpenHallMcu(driver_options);
  hall_mcu::DeviceInfo info;
  if (auto r = sensor->Identify(&info); !r.ok) throw std::runtime_error(r.message);
  spdlog::info("hall record: {} is {}", driver_options.device, info.ToString());

  acquisition::HallCsvWriter writer(args.out);
  std::mutex sink_mu;
  std::string sink_error;
  acquisition::HallRecorder* recorder_ptr = nullptr;
  acquisition::HallRecorder recorder(
      *sensor,
      [&](const hall_mcu::HallBatch& batch) {
        try {
          writer.Write(batch);
        } catch (const std::exception& e) {
          std::lock_guard lock(sink_mu);
          if (sink_error.empty()) sink_error = e.what();
          if (recorder_ptr != nullptr) recorder_ptr->Stop();
        }
      },
      options);
  recorder_ptr = &recorder;

  struct sigaction action {};
  action.sa_handler = OnRecordSignal;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  recorder.Start();
  while (!recorder.WaitForReader(std::chrono::milliseconds(1000))) {
    if (g_record_interrupted) recorder.Stop();
    spdlog::info("hall record: {}", FormatCounts(recorder.Counts()));
  }
  const acquisition::HallRecorderResult result = recorder.Wait();
  writer.Close();
  std::printf("%s: %s; wrote %llu readings to %s and %llu clock edges to %s\n",
              acquisition::ToString(result.end), FormatCounts(result.counts).c_str(),
              static_cast<unsigned long long>(writer.readings_written()), args.out.c_str(),
              static_cast<unsigned long long>(writer.edges_written()),
              acquisition::ClockCsvPathFor(args.out).c_str());
  std::fflush(stdout);
  if (!sink_error.empty()) throw std::runtime_error("hall record: " + sink_error);
  switch (result.end) {
    case acquisition::RecorderEnd::kDuration:
    case acquisition::RecorderEnd::kEndOfData:
    case acquisition::RecorderEnd::kStopped:
      return;
    default:
      throw std::runtime_error("hall record ended early (" +
                               std::string(acquisition::ToString(result.end)) +
                               "): " + result.message);
  }
}

void AddHallIoCommands(CLI::App& app) {
  {
    CLI::App* mock = GetOrAddSubcommand(app, "mock", "Serve mock instruments");
    auto* cmd = mock->add_subcommand(
        "mcu", "Mock Hall MCU on a pseudo-terminal; prints 'ready PATH' and streams until stopped");
    auto args = std::make_shared<MockArgs>();
    cmd->add_option("--link", args->link, "symlink to create to the pty device")->required();
    cmd->add_option("--mode", args->mode, "scan|background|marg (synthetic data)")
        ->check(CLI::IsMember({"scan", "background", "marg"}));
    cmd->add_option("--speed", args->speed, "1 = real time, 0 = as fast as the reader takes it")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--source", args->source,
                    "rig: the rig simulator's Hall model (scan = actual recording, background); "
                    "synthetic: built-in sinusoids (marg mode is always synthetic)")
        ->check(CLI::IsMember({"rig", "synthetic"}));
    cmd->add_option("--sim-config", args->sim_config, "rig simulator options (YAML), --source rig")
        ->check(CLI::ExistingFile);
    cmd->add_option("--seconds", args->seconds,
                    "MCU time of data; 0 = endless (synthetic) or the simulator's duration (rig)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--seed", args->seed, "seed of the synthetic data and fault positions");
    cmd->add_option("--replay", args->replay,
                    "replay an interchange Hall CSV (and its <stem>_clock.csv) instead")
        ->check(CLI::ExistingFile);
    cmd->add_flag("--stream-on-open", args->stream_on_open,
                  "stream without waiting for a start command");
    cmd->add_option("--fault", args->faults,
                    "inject a fault at a data frame: flip@N, drop@N, reset@N, stall@N[:ms]");
    cmd->callback([args] { RunMockMcu(*args); });
  }
  {
    CLI::App* hall = GetOrAddSubcommand(app, "hall", "Hall sensor: record, calibrate, predict");
    auto* cmd = hall->add_subcommand(
        "record", "Record Hall readings and clock edges from the MCU into interchange CSVs");
    auto args = std::make_shared<RecordArgs>();
    cmd->add_option("--rig", args->rig, "rig configuration with a hall_mcu: section")
        ->check(CLI::ExistingFile);
    cmd->add_option("--device", args->device, "serial device, e.g. /dev/ttyACM0 (overrides --rig)");
    cmd->add_option("--seconds", args->seconds, "MCU time to record; 0 = until end of data/^C")
        ->required()
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--out", args->out,
                    "readings CSV; clock edges go to <stem>_clock.csv (neither may exist)")
        ->required();
    cmd->add_option("--baud", args->baud,
                    "baud rate (ignored by USB CDC; default: the rig file's, else 921600)");
    cmd->add_option("--rate", args->rate_hz, "sample rate to set, Hz")->check(CLI::Range(1, 5000));
    cmd->add_option("--gain", args->gain_sel, "MLX90393 GAIN_SEL to set (0..7)")
        ->check(CLI::Range(0, 7));
    auto* gain = cmd->get_option("--gain");
    gain->description(
        "MLX90393 GAIN_SEL to set (0..7); replaces the rig file's whole sensor section, with "
        "--res-xy / --res-z (default 0) and the default OSR and digital filter");
    cmd->add_option("--res-xy", args->res_xy, "RES_X = RES_Y with --gain (0..3)")
        ->check(CLI::Range(0, 3))
        ->needs(gain);
    cmd->add_option("--res-z", args->res_z, "RES_Z with --gain (0..3)")
        ->check(CLI::Range(0, 3))
        ->needs(gain);
    cmd->add_option("--stall-timeout-ms", args->stall_timeout_ms,
                    "silence after which the recording fails (default: the rig file's, else "
                    "500)")
        ->check(CLI::Range(1, 600000));
    cmd->callback([args] { RunHallRecord(*args); });
  }
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/55, AddHallIoCommands);

}  // namespace msmcal::app
