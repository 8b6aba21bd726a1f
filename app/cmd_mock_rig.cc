// The digital twin behind the real wires (docs/twin.md):
//   msmcal mock rig --rig RIG.yaml --hands SOCKET [--world sim.yaml] [--seed N] [--exposure S]
//                   [--hall-link PATH]
//     serves both generators, the camera and the Hall MCU of RIG.yaml from one simulated world
//     until SIGINT/SIGTERM; the world's physical state changes only through SOCKET.
//   msmcal mock hands --socket SOCKET [--truth-out DIR] [--timeout-ms MS]
//     reads one set-up JSON on stdin and performs it on the twin (exit 0 once in effect); with
//     --truth-out, writes the twin's ground truth for the drive and trigger table last applied.
// Exit codes of `mock hands`: 0 done, 2 malformed set-up, 3 the twin refused it, 1 twin
// unreachable or other failure.

#include <signal.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <iterator>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "app/command_registry.h"
#include "app/stop_signal.h"
#include "mocks/rig/sim_options.h"
#include "simulation/twin/hands_protocol.h"
#include "simulation/twin/physical_twin.h"
#include "simulation/twin/twin_rig_config.h"

namespace {

using msmcal::app::StopSignal;

namespace fs = std::filesystem;
namespace twin = msmcal::twin;

struct RigArgs {
  std::string rig;
  std::string hands;
  std::string world;
  std::optional<uint64_t> seed;  // none: the world's
  double exposure_s = 0.5;
  std::string hall_link;
};

struct HandsArgs {
  std::string socket;
  std::string truth_out;
  int timeout_ms = 30000;
};

void ServeRig(const RigArgs& args) {
  StopSignal stop;  // before any thread starts
  const msmcal::sim::SimOptions world =
      args.world.empty() ? msmcal::sim::SimOptions{} : msmcal::sim::LoadSimOptions(args.world);
  twin::PhysicalTwinOptions o = twin::TwinOptionsFromRigFile(args.rig, world);
  if (args.seed) o.sim.seed = *args.seed;
  o.hands_socket = args.hands;
  o.exposure_s = args.exposure_s;
  if (!args.hall_link.empty()) o.hall_link_path = args.hall_link;
  twin::PhysicalTwin rig(o);
  std::cout << "twin: generators on 127.0.0.1:" << rig.generator_port(1)
            << " and 127.0.0.1:" << rig.generator_port(2) << "\n"
            << "twin: camera " << o.sim.camera.width << "x" << o.sim.camera.height << " on "
            << o.camera_address << "\n"
            << "twin: Hall MCU on " << rig.hall_device()
            << (o.hall_link_path.empty() ? "" : " (" + o.hall_link_path + ")") << "\n"
            << "twin: hands on " << args.hands << "\n"
            << "twin: ready" << std::endl;
  const int signo = stop.Wait();
  std::cout << "twin: stopping (signal " << signo << ")" << std::endl;
}

void Hands(const HandsArgs& args) {
  std::string line;
  if (!args.truth_out.empty()) {
    twin::HandsRequest r;
    r.kind = twin::HandsRequest::Kind::kTruthRequest;
    r.dir = fs::absolute(args.truth_out).lexically_normal().string();
    line = twin::FormatHandsRequest(r);
  } else {
    const std::string text((std::istreambuf_iterator<char>(std::cin)),
                           std::istreambuf_iterator<char>());
    try {
      (void)twin::ParseHandsRequest(text);  // refuse a malformed set-up before the twin sees it
    } catch (const std::invalid_argument& e) {
      std::cerr << "msmcal mock hands: malformed set-up: " << e.what() << std::endl;
      std::exit(2);
    }
    // One line on the wire: the document re-serialised compactly (unknown fields dropped).
    line = twin::FormatHandsRequest(twin::ParseHandsRequest(text));
  }
  twin::HandsReply reply;
  try {
    reply = twin::SendHandsRequest(args.socket, line, args.timeout_ms);
  } catch (const std::exception& e) {
    std::cerr << "msmcal mock hands: " << e.what() << std::endl;
    std::exit(1);
  }
  if (!reply.ok) {
    std::cerr << "msmcal mock hands: the twin refused: " << reply.error << std::endl;
    std::exit(3);
  }
  std::cout << "twin: done (generation " << reply.generation << ")" << std::endl;
}

void AddMockRigCommands(CLI::App& app) {
  auto* mock = msmcal::app::GetOrAddSubcommand(app, "mock", "Serve mock instruments");
  auto rig_args = std::make_shared<RigArgs>();
  auto* rig = mock->add_subcommand(
      "rig",
      "Serve the digital twin: both generators, the camera and the Hall MCU of the rig file "
      "from one simulated world, until SIGINT/SIGTERM (docs/twin.md)");
  rig->add_option("--rig", rig_args->rig, "Rig file (YAML)")->required()->check(CLI::ExistingFile);
  rig->add_option("--hands", rig_args->hands, "Unix socket the twin's hands listen on")->required();
  rig->add_option("--world", rig_args->world,
                  "The world's simulation config (default: built-in = config/sim.yaml)")
      ->check(CLI::ExistingFile);
  rig->add_option("--seed", rig_args->seed, "Override the world's seed");
  rig->add_option("--exposure", rig_args->exposure_s,
                  "Camera integration window per frame, s (>= one pattern period shows every "
                  "pulse)");
  rig->add_option("--hall-link", rig_args->hall_link,
                  "Where the Hall MCU's pty is symlinked (default: the rig file's "
                  "hall_mcu.device)");
  rig->callback([rig_args] { ServeRig(*rig_args); });

  auto hands_args = std::make_shared<HandsArgs>();
  auto* hands = mock->add_subcommand(
      "hands",
      "Perform one set-up (JSON on stdin) on a running twin, or write its ground truth "
      "(--truth-out); exits once the change is in effect");
  hands->add_option("--socket", hands_args->socket, "The twin's hands socket")->required();
  hands->add_option("--truth-out", hands_args->truth_out,
                    "Write the twin's truth (truth/ files of `msmcal simulate`) into this folder");
  hands->add_option("--timeout-ms", hands_args->timeout_ms, "How long to wait for the twin")
      ->check(CLI::Range(1, 3600000));
  hands->callback([hands_args] { Hands(*hands_args); });
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/74, AddMockRigCommands);
