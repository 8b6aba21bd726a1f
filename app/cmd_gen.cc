// Function generator commands:
//   msmcal gen identify --rig CONFIG
//   msmcal gen apply --rig CONFIG [--detach] [--triggers-out FILE] [--transcript FILE]
//                    [--watchdog-log FILE]
//   msmcal gen off --rig CONFIG
//   msmcal mock generators --rig CONFIG [--unlocked] [--no-trigger-cable]
//                          [--fault unitN:SPEC]... [--second-connection serve|queue|close]
//   msmcal mock generator --port P [--idn TEXT] [--fault SPEC]... [--second-connection MODE]
//                         [--vxi11 [--vxi11-core-port N] [--portmapper-port N]]
// Faults and the second-connection modes: mocks/generator/mock_server.h, docs/fault-campaign.md.
#include <signal.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "app/command_registry.h"
#include "app/stop_signal.h"
#include "drivers/generator/rig_generators.h"
#include "drivers/generator/safe_state.h"
#include "drivers/generator/watchdog.h"
#include "mocks/generator/mock_server.h"
#include "mocks/generator/vxi11_server.h"

namespace {

using msmcal::app::StopSignal;

using msmcal::gen::FunctionGenerator;
using msmcal::gen::RigGeneratorConfig;

RigGeneratorConfig LoadValidated(const std::string& path) {
  RigGeneratorConfig config = msmcal::gen::LoadRigGeneratorConfig(path);
  if (const std::string e = config.Validate(); !e.empty()) {
    throw std::runtime_error(path + ": invalid configuration: " + e);
  }
  return config;
}

struct GenArgs {
  std::string rig = "config/rig.yaml";
  bool detach = false;
  std::string triggers_out;
  std::string transcript;
  std::string watchdog_log;
};

void Identify(const GenArgs& args) {
  const RigGeneratorConfig config = LoadValidated(args.rig);
  for (const auto* unit : {&config.unit1, &config.unit2}) {
    auto g = msmcal::gen::OpenKeysight33500(*unit);
    const auto id = g->Identify();
    if (!id.ok()) throw std::runtime_error(id.status().message);
    const auto options = g->Options();
    if (!options.ok()) throw std::runtime_error(options.status().message);
    const auto locked = g->ReferenceLocked();
    if (!locked.ok()) throw std::runtime_error(locked.status().message);
    std::printf("%s %s:%d: %s %s serial %s firmware %s, options '%s', reference %s\n",
                unit->name.c_str(), unit->link.host.c_str(), unit->link.port,
                id->manufacturer.c_str(), id->model.c_str(), id->serial.c_str(),
                id->firmware.c_str(), options->c_str(), *locked ? "external (locked)" : "internal");
  }
}

void Apply(const GenArgs& args) {
  const RigGeneratorConfig config = LoadValidated(args.rig);
  const msmcal::gen::RigSignalPlan plan = msmcal::gen::PlanRigSignals(config.signals);
  std::unique_ptr<std::ofstream> transcript;
  msmcal::scpi::TranscriptSink sink1, sink2;
  if (!args.transcript.empty()) {
    transcript = std::make_unique<std::ofstream>(args.transcript);
    if (!*transcript) throw std::runtime_error(args.transcript + ": cannot write");
    auto make = [&](const std::string& unit) {
      return [out = transcript.get(), unit](const msmcal::scpi::TranscriptEntry& e) {
        *out << e.time_ns << ' ' << unit << (e.to_instrument ? " << " : " >> ") << e.text << '\n';
      };
    };
    sink1 = make(config.unit1.name);
    sink2 = make(config.unit2.name);
  }
  auto master = msmcal::gen::OpenKeysight33500(config.unit1, sink1);
  auto slave = msmcal::gen::OpenKeysight33500(config.unit2, sink2);
  msmcal::gen::RigGenerators rig(*master, *slave);
  // The watchdog (docs/watchdog.md) covers what the guard cannot: SIGKILL, an OOM kill, a crash.
  // Not with --detach: the outputs are meant to stay on after this process.
  std::unique_ptr<msmcal::gen::Watchdog> watchdog;
  if (!args.detach) {
    watchdog =
        msmcal::gen::Watchdog::Start(msmcal::gen::SelfWatchdogLaunch("msmcal", "watchdog"),
                                     msmcal::gen::WatchdogConfigFor(config, args.watchdog_log));
  }
  msmcal::gen::SafeStateGuard guard([&rig, &watchdog, &transcript] {
    const bool confirmed = rig.SafeState();
    // On a signal the process ends right after this action (no destructor runs): the safe
    // state's own exchange must reach the transcript now.
    if (transcript) transcript->flush();
    if (confirmed) {
      if (watchdog) watchdog->StandDown();
    } else if (watchdog) {  // not confirmed by this process: the watchdog acts now
      const msmcal::gen::WatchdogHandOver h = msmcal::gen::HandOverToWatchdog(*watchdog);
      msmcal::gen::SafeStateGuard::ReportHandedOver(h.confirmed, h.text);
    } else {
      msmcal::gen::SafeStateGuard::ReportUnconfirmed();
    }
  });
  rig.Apply(plan);
  const auto& t = plan.trigger;
  std::printf(
      "signals running: pattern period %.9g s, %zu triggers, arb %lld points at %.9g Sa/s, "
      "max quantisation error %.3g s, duty %.3g\n",
      t.pattern_period_s, t.times_s.size(), static_cast<long long>(t.arb.points),
      t.arb.sample_rate_sps, t.max_quantisation_error_s, t.duty);
  if (!args.triggers_out.empty()) {
    std::ofstream out(args.triggers_out);
    out << "j,t_s\n";
    out.precision(17);
    for (size_t j = 0; j < t.times_s.size(); ++j) out << j << ',' << t.times_s[j] << '\n';
    if (!out) throw std::runtime_error(args.triggers_out + ": cannot write");
  }
  if (transcript) transcript->flush();
  if (args.detach) {
    guard.Disarm();
    std::printf("detached: outputs stay on (msmcal gen off --rig %s turns them off)\n",
                args.rig.c_str());
    return;
  }
  std::printf("Ctrl-C (SIGINT) or SIGTERM turns the outputs off and exits\n");
  std::fflush(stdout);
  guard.WaitForSignal();
}

void Off(const GenArgs& args) {
  const RigGeneratorConfig config = LoadValidated(args.rig);
  bool all = true;
  for (const auto* unit : {&config.unit1, &config.unit2}) {
    auto g = msmcal::gen::OpenKeysight33500(*unit);
    const bool ok = g->SafeState();
    std::printf("%s: outputs %s\n", unit->name.c_str(), ok ? "off" : "NOT CONFIRMED OFF");
    all = all && ok;
  }
  if (!all) throw std::runtime_error("safe state not confirmed by every generator");
}

void AddGenCommands(CLI::App& app) {
  auto* gen =
      msmcal::app::GetOrAddSubcommand(app, "gen", "Function generators (two Keysight 33520B)");
  auto args = std::make_shared<GenArgs>();
  auto rig_option = [&](CLI::App* sub) {
    sub->add_option("--rig", args->rig, "Rig configuration (YAML)")
        ->required()
        ->check(CLI::ExistingFile);
  };
  auto* identify = gen->add_subcommand(
      "identify", "Print identity, options and reference lock of both generators");
  rig_option(identify);
  identify->callback([args] {
    const msmcal::gen::OpenGeneratorsGuard signals;  // from the start: docs/watchdog.md
    Identify(*args);
  });

  auto* apply = gen->add_subcommand(
      "apply",
      "Configure the four phase-locked rig signals, start them, and keep them running "
      "until SIGINT/SIGTERM (then outputs off)");
  rig_option(apply);
  apply->add_flag("--detach", args->detach, "Exit leaving the outputs on");
  apply->add_option("--triggers-out", args->triggers_out, "Write the trigger table (CSV j,t_s)");
  apply->add_option("--transcript", args->transcript, "Write the SCPI transcript");
  apply->add_option("--watchdog-log", args->watchdog_log,
                    "File the watchdog appends its report to if this process is killed "
                    "(default: stderr only)");
  apply->callback([args] {
    const msmcal::gen::OpenGeneratorsGuard signals;  // from the start: docs/watchdog.md
    Apply(*args);
  });

  auto* off = gen->add_subcommand("off", "Turn every generator output off");
  rig_option(off);
  off->callback([args] {
    const msmcal::gen::OpenGeneratorsGuard signals;  // from the start: docs/watchdog.md
    Off(*args);
  });
}

struct MockArgs {
  std::string rig = "config/rig.yaml";
  bool unlocked = false;
  bool no_trigger_cable = false;
  int port = 0;
  std::string idn;
  std::vector<std::string> faults;
  std::string second_connection = "serve";
  bool vxi11 = false;
  int vxi11_core_port = 0;
  int portmapper_port = 111;
};

// Prints what a mock unit saw, on stop: the fault campaign reads it (docs/fault-campaign.md).
void PrintServerSummary(const std::string& name, const msmcal::sim::MockGeneratorServer& server) {
  const msmcal::sim::ServerStats st = server.Stats();
  std::cout << name << ": " << st.connections << " connection(s), " << st.messages
            << " message(s), " << st.faults_applied << " fault(s) applied, "
            << st.connections_turned_away << " connection(s) turned away" << std::endl;
}

void ServeGenerators(const MockArgs& args) {
  const RigGeneratorConfig config = msmcal::gen::LoadRigGeneratorConfig(args.rig);
  for (const auto* unit : {&config.unit1, &config.unit2}) {
    if (unit->link.host != "127.0.0.1" && unit->link.host != "localhost") {
      throw std::runtime_error(args.rig + ": generators." + unit->name + ".host = " +
                               unit->link.host + ": the mock serves on 127.0.0.1 only");
    }
  }
  StopSignal stop;
  msmcal::sim::GeneratorPairOptions o;
  o.port1 = config.unit1.link.port;
  o.port2 = config.unit2.link.port;
  o.reference_wired = !args.unlocked;
  o.trigger_wired = !args.no_trigger_cable;
  o.limits1.second_connection = o.limits2.second_connection =
      msmcal::sim::ParseSecondConnection(args.second_connection);
  std::vector<std::pair<int, msmcal::sim::Fault>> faults;
  for (const std::string& f : args.faults) {
    const bool unit1 = f.rfind("unit1:", 0) == 0, unit2 = f.rfind("unit2:", 0) == 0;
    if (!unit1 && !unit2)
      throw std::invalid_argument("--fault '" + f + "': name the unit: unit1:SPEC or unit2:SPEC");
    faults.emplace_back(unit1 ? 1 : 2, msmcal::sim::ParseFault(f.substr(6)));
  }
  msmcal::sim::MockGeneratorPair pair(o);
  for (const auto& [unit, fault] : faults) pair.server(unit).InjectFault(fault);
  std::cout << "listening on 127.0.0.1:" << pair.port(1) << " (" << config.unit1.name << ")\n"
            << "listening on 127.0.0.1:" << pair.port(2) << " (" << config.unit2.name << ")"
            << std::endl;
  stop.Wait();
  PrintServerSummary(config.unit1.name, pair.server(1));
  PrintServerSummary(config.unit2.name, pair.server(2));
}

void ServeGenerator(const MockArgs& args) {
  StopSignal stop;
  msmcal::sim::UnitOptions u;
  if (!args.idn.empty()) u.identity = args.idn;
  msmcal::sim::Mock33520B unit(u, nullptr);
  msmcal::sim::ServerLimits limits;
  limits.second_connection = msmcal::sim::ParseSecondConnection(args.second_connection);
  msmcal::sim::MockGeneratorServer server(unit, args.port, limits);
  for (const std::string& f : args.faults) server.InjectFault(msmcal::sim::ParseFault(f));
  server.Start();
  std::cout << "listening on 127.0.0.1:" << server.port() << std::endl;
  // VXI-11 on the same unit (one instrument, both wires): docs/protocols/generator-scpi.md.
  std::unique_ptr<msmcal::sim::Vxi11Server> vxi11;
  if (args.vxi11) {
    msmcal::sim::Vxi11ServerOptions o;
    o.core_port = args.vxi11_core_port;
    o.portmapper_port = args.portmapper_port;
    vxi11 = std::make_unique<msmcal::sim::Vxi11Server>(unit, o);
    vxi11->Start();
    if (!vxi11->portmapper_error().empty()) {
      std::cerr << "warning: " << vxi11->portmapper_error() << std::endl;
    }
    std::cout << "VXI-11 core channel on 127.0.0.1:" << vxi11->core_port()
              << ", abort channel on 127.0.0.1:" << vxi11->abort_port();
    if (vxi11->portmapper_port() > 0) {
      std::cout << ", portmapper on 127.0.0.1:" << vxi11->portmapper_port();
    }
    std::cout << std::endl;
  }
  stop.Wait();
  if (vxi11) vxi11->Stop();
  PrintServerSummary("generator", server);
}

void AddMockGeneratorCommands(CLI::App& app) {
  auto* mock = msmcal::app::GetOrAddSubcommand(app, "mock", "Serve mock instruments");
  auto args = std::make_shared<MockArgs>();
  auto* pair =
      mock->add_subcommand("generators",
                           "Serve the rig's two mock 33520B units on 127.0.0.1 (ports from the rig "
                           "configuration) until SIGINT/SIGTERM");
  pair->add_option("--rig", args->rig, "Rig configuration (YAML)")
      ->required()
      ->check(CLI::ExistingFile);
  pair->add_flag("--unlocked", args->unlocked, "Leave the 10 MHz reference cable unplugged");
  pair->add_flag("--no-trigger-cable", args->no_trigger_cable, "Leave the trigger cable unplugged");
  auto add_fault_options = [&](CLI::App* cmd, const char* fault_help) {
    cmd->add_option("--fault", args->faults, fault_help);
    cmd->add_option("--second-connection", args->second_connection,
                    "A second SCPI connection while one is open: serve (default), queue (accept, "
                    "serve once the first closes) or close (accept and close it)")
        ->check(CLI::IsMember({"serve", "queue", "close"}));
  };
  add_fault_options(pair,
                    "Inject a fault (repeatable; off by default): unitN:KIND[,after=N]"
                    "[,match=TEXT][,ms=MS], KIND drop|freeze|delay|garbage|drop-mid-reply "
                    "(docs/fault-campaign.md)");
  pair->callback([args] { ServeGenerators(*args); });

  auto* one = mock->add_subcommand("generator",
                                   "Serve one mock 33520B on 127.0.0.1:PORT until SIGINT/SIGTERM");
  one->add_option("--port", args->port, "TCP port (0 = any free port)")
      ->required()
      ->check(CLI::Range(0, 65535));
  one->add_option("--idn", args->idn, "*IDN? reply");
  add_fault_options(one,
                    "Inject a fault (repeatable; off by default): KIND[,after=N][,match=TEXT]"
                    "[,ms=MS], KIND drop|freeze|delay|garbage|drop-mid-reply");
  one->add_flag("--vxi11", args->vxi11,
                "Also serve VXI-11 (core and abort channels, and a portmapper on port 111 when it "
                "can be bound: root or `unshare -rn`), fed into the same unit");
  one->add_option("--vxi11-core-port", args->vxi11_core_port,
                  "TCP port of the VXI-11 core channel (0 = any free port; the portmapper tells "
                  "clients which)")
      ->check(CLI::Range(0, 65535));
  one->add_option("--portmapper-port", args->portmapper_port,
                  "TCP and UDP port of the portmapper (111 as on the instrument; -1 = none)")
      ->check(CLI::Range(-1, 65535));
  one->callback([args] {
    if (!args->vxi11 && (args->vxi11_core_port != 0 || args->portmapper_port != 111)) {
      throw std::invalid_argument("--vxi11-core-port and --portmapper-port need --vxi11");
    }
    ServeGenerator(*args);
  });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/30, AddGenCommands);
MSMCAL_REGISTER_COMMANDS(/*order=*/71, AddMockGeneratorCommands);
