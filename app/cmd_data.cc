// Data commands: `msmcal import`, `msmcal export`, `msmcal sessions list|show` and
// `msmcal interchange check` (the interchange format and the session store, issues 2 and 9).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>

#include "app/command_registry.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/store/catalogue.h"
#include "sessions/store/session_store.h"
#include "sessions/store/transfer.h"

namespace msmcal::app {
namespace {

namespace fs = std::filesystem;

// Not "sessions": run from a checkout, that would write into the source module of that name.
constexpr const char* kDefaultRoot = "msmcal-sessions";

std::string Num(double v) { return interchange::FormatDouble(v); }

// "20261123T114005Z-<base>", made unique under root.
fs::path NewSessionDir(const fs::path& root, const std::string& name, const fs::path& folder,
                       const store::Clock& clock) {
  std::string base = name;
  if (base.empty()) {
    std::string stamp = store::FormatUtc(clock.NowNs());
    std::erase(stamp, '-');
    std::erase(stamp, ':');
    std::string folder_name = fs::absolute(folder).lexically_normal().filename().string();
    if (folder_name.empty()) folder_name = fs::absolute(folder).parent_path().filename().string();
    base = stamp + "-" + folder_name;
  } else if (name.find('/') != std::string::npos || name == "." || name == ".." || name[0] == '.') {
    throw std::runtime_error("--name '" + name + "' must be a plain folder name");
  }
  fs::path dir = root / base;
  if (!name.empty() && fs::exists(dir)) {
    throw std::runtime_error("session '" + dir.string() + "' already exists");
  }
  for (int i = 2; fs::exists(dir); ++i) dir = root / (base + "-" + std::to_string(i));
  return dir;
}

std::string RecordingSummary(const dataset::Recording& r) {
  std::ostringstream s;
  int estimate = 0;
  for (const auto& b : r.beams) estimate += b.role == dataset::BeamRole::kEstimate;
  std::map<std::string, int> kinds;
  for (const auto& f : r.step2) ++kinds[dataset::ToString(f.kind)];
  s << "format " << r.format << "\n"
    << "camera " << r.camera.width << "x" << r.camera.height << ", fx " << Num(r.camera.fx)
    << ", fy " << Num(r.camera.fy) << "\n"
    << "boards world " << r.world_board.cols << "x" << r.world_board.rows << " @ "
    << Num(r.world_board.square_mm) << " mm, sliding " << r.sliding_board.cols << "x"
    << r.sliding_board.rows << " @ " << Num(r.sliding_board.square_mm) << " mm\n"
    << "beams " << r.beams.size() << " (" << estimate << " estimate, " << r.beams.size() - estimate
    << " validate)\n"
    << "drive fast " << Num(r.drive.fast.frequency_hz) << " Hz " << Num(r.drive.fast.amplitude_vpp)
    << " Vpp, slow " << Num(r.drive.slow.frequency_hz) << " Hz " << Num(r.drive.slow.amplitude_vpp)
    << " Vpp, pattern period " << Num(r.drive.pattern_period_s) << " s\n"
    << "triggers " << r.triggers.size() << "\n"
    << "step1 frames " << r.step1.size() << "\n"
    << "step2 frames " << r.step2.size() << " (neutral " << kinds["neutral"] << ", fast_only "
    << kinds["fast_only"] << ", scan " << kinds["scan"] << ")\n";
  auto hall = [&](const char* name, const std::optional<dataset::HallRecording>& h) {
    if (h) {
      s << "hall " << name << " " << h->readings.size() << " readings, " << h->clock_edges_us.size()
        << " clock edges\n";
    }
  };
  hall("actual", r.hall_actual);
  hall("background", r.hall_background);
  auto marg = [&](const char* name, const std::optional<dataset::MargRecording>& m) {
    if (m) {
      s << "marg " << name << " " << m->samples.size() << " samples"
        << (m->has_inertial ? "" : " (magnetometer only)") << "\n";
    }
  };
  marg("plane_rotation", r.marg_plane_rotation);
  marg("free_rotation", r.marg_free_rotation);
  marg("validation", r.marg_validation);
  return s.str();
}

void AddImport(CLI::App& app) {
  struct Args {
    std::string folder, root = kDefaultRoot, name;
    store::ImportOptions options;
  };
  auto a = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("import", "Import an interchange folder as a new session");
  cmd->add_option("FOLDER", a->folder, "interchange folder (../shared/docs/interchange-format.md)")
      ->required();
  cmd->add_option("--root", a->root, "sessions root folder")->capture_default_str();
  cmd->add_option("--name", a->name, "session folder name (default: <UTC time>-<folder name>)");
  cmd->add_option("--rig", a->options.rig_id, "rig id recorded in the catalogue");
  cmd->add_option("--mirror", a->options.mirror_id, "mirror id recorded in the catalogue");
  cmd->add_option("--note", a->options.note, "free text");
  cmd->callback([a] {
    const store::SystemClock clock;
    const fs::path dir = NewSessionDir(a->root, a->name, a->folder, clock);
    try {
      auto session = store::ImportInterchange(a->folder, dir, clock, a->options);
      std::cout << session->dir().string() << "\n";
    } catch (const interchange::InterchangeError& e) {
      throw std::runtime_error("import " + a->folder + ": " + e.what());
    }
  });
}

void AddExport(CLI::App& app) {
  struct Args {
    std::string session, out, root = kDefaultRoot;
  };
  auto a = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("export", "Export a session as an interchange folder");
  cmd->add_option("SESSION", a->session, "session folder, or its name under --root")->required();
  cmd->add_option("--out", a->out, "output folder (must not exist or be empty)")->required();
  cmd->add_option("--root", a->root, "sessions root folder")->capture_default_str();
  cmd->callback([a] {
    const store::SystemClock clock;
    const auto session =
        store::SessionStore::Open(store::ResolveSession(a->session, a->root), clock,
                                  /*read_only=*/true);
    store::ExportInterchange(*session, a->out);
    std::cout << a->out << "\n";
  });
}

void AddSessions(CLI::App& app) {
  auto* sessions = GetOrAddSubcommand(app, "sessions", "The session catalogue");

  struct ListArgs {
    std::string root = kDefaultRoot, rig, mirror, since;
  };
  auto l = std::make_shared<ListArgs>();
  auto* list = sessions->add_subcommand("list", "List sessions under the root folder");
  list->add_option("--root", l->root, "sessions root folder")->capture_default_str();
  list->add_option("--rig", l->rig, "only this rig id");
  list->add_option("--mirror", l->mirror, "only this mirror id");
  list->add_option("--since", l->since,
                   "only sessions created on or after (YYYY-MM-DD[THH:MM:SSZ], UTC)");
  list->callback([l] {
    store::CatalogueFilter filter;
    if (!l->rig.empty()) filter.rig_id = l->rig;
    if (!l->mirror.empty()) filter.mirror_id = l->mirror;
    if (!l->since.empty()) {
      filter.since_ns = store::ParseUtc(l->since);
      if (!filter.since_ns) {
        throw std::runtime_error("--since '" + l->since +
                                 "': expected YYYY-MM-DD or YYYY-MM-DDTHH:MM:SSZ");
      }
    }
    const store::SystemClock clock;
    const auto entries = store::ListSessions(l->root, filter, clock);
    // Columns as wide as their widest cell. RESULT: the headline RMS of results/summary.json
    // (the validation beam's error in px for `msmcal solve` results).
    std::vector<std::vector<std::string>> rows = {{"SESSION", "CREATED (UTC)", "RIG", "MIRROR",
                                                   "FAST Hz/Vpp", "SLOW Hz/Vpp", "FRAMES",
                                                   "RESULT RMS"}};
    for (const auto& e : entries) {
      if (!e.error.empty()) {
        rows.push_back({e.id, "unreadable: " + e.error});
        continue;
      }
      char rms[32] = "-";
      if (e.result_rms) std::snprintf(rms, sizeof(rms), "%.4g", *e.result_rms);
      rows.push_back({e.id, store::FormatUtc(e.created_ns), e.rig_id.empty() ? "-" : e.rig_id,
                      e.mirror_id.empty() ? "-" : e.mirror_id,
                      Num(e.fast_frequency_hz) + "/" + Num(e.fast_amplitude_vpp),
                      Num(e.slow_frequency_hz) + "/" + Num(e.slow_amplitude_vpp),
                      std::to_string(e.frames), rms});
    }
    std::vector<size_t> width(rows[0].size(), 0);
    for (const auto& r : rows)
      if (r.size() == width.size())
        for (size_t c = 0; c < r.size(); ++c) width[c] = std::max(width[c], r[c].size());
    for (const auto& r : rows) {
      std::string line;
      for (size_t c = 0; c < r.size(); ++c) {
        line += r[c];
        if (c + 1 < r.size() && r.size() == width.size())
          line += std::string(width[c] - r[c].size() + 2, ' ');
        else if (c + 1 < r.size())
          line += "  ";
      }
      std::printf("%s\n", line.c_str());
    }
    std::printf("%zu session(s) under %s\n", entries.size(), l->root.c_str());
  });

  struct ShowArgs {
    std::string session, root = kDefaultRoot;
    int events = 10;
  };
  auto s = std::make_shared<ShowArgs>();
  auto* show = sessions->add_subcommand("show", "Show one session's details");
  show->add_option("SESSION", s->session, "session folder, or its name under --root")->required();
  show->add_option("--root", s->root, "sessions root folder")->capture_default_str();
  show->add_option("--events", s->events, "how many of the last events to print")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  show->callback([s] {
    const store::SystemClock clock;
    const auto session = store::SessionStore::Open(store::ResolveSession(s->session, s->root),
                                                   clock, /*read_only=*/true);
    const auto meta = session->AllMeta();
    auto get = [&](const char* key) {
      const auto it = meta.find(key);
      return it == meta.end() || it->second.empty() ? std::string("-") : it->second;
    };
    int64_t created_ns = 0;
    try {
      created_ns = std::stoll(get("created_ns"));
    } catch (const std::exception&) {
    }
    std::cout << "session  " << session->dir().string() << "\n"
              << "created  " << store::FormatUtc(created_ns) << "\n"
              << "rig      " << get("rig_id") << "\n"
              << "mirror   " << get("mirror_id") << "\n"
              << "note     " << get("note") << "\n"
              << "drive    fast " << get("drive.fast.frequency_hz") << " Hz "
              << get("drive.fast.amplitude_vpp") << " Vpp, slow " << get("drive.slow.frequency_hz")
              << " Hz " << get("drive.slow.amplitude_vpp") << " Vpp\n";
    if (meta.count("import.source")) std::cout << "imported " << get("import.source") << "\n";
    const auto instruments = session->Instruments();
    for (const auto& [role, identity] : instruments) {
      std::cout << "instrument " << role << ": " << identity << "\n";
    }
    std::cout << "steps   ";
    for (const auto& [name, state] : session->Steps()) {
      std::cout << " " << name << "=" << store::ToString(state);
    }
    std::cout << "\n";
    const auto counts = session->Counts();
    int step1 = 0, step2 = 0, rejected = 0;
    for (const auto& f : session->Frames()) {
      (f.step == "step1" ? step1 : step2)++;
      rejected += !f.accepted;
    }
    std::cout << "frames   " << counts.frames << " (step1 " << step1 << ", step2 " << step2
              << ", rejected " << rejected << ")\n"
              << "triggers " << counts.triggers << "\n";
    for (const auto& [name, n] : counts.hall_readings) {
      const auto edges = counts.clock_edges.find(name);
      std::cout << "hall     " << name << ": " << n << " readings, "
                << (edges == counts.clock_edges.end() ? 0 : edges->second) << " clock edges\n";
    }
    std::cout << "results ";
    for (const auto& name : session->ResultNames()) std::cout << " " << name;
    if (const auto rms = store::ResultRms(*session)) std::cout << "  (RMS " << Num(*rms) << ")";
    std::cout << "\n";
    const auto attachments = session->AttachmentPaths();
    if (!attachments.empty()) {
      std::cout << "kept    ";
      for (const auto& p : attachments) std::cout << " " << p;
      std::cout << "\n";
    }
    std::cout << "events   " << counts.events << " (last " << s->events << ")\n";
    for (const auto& e : session->Events(s->events)) {
      std::cout << "  " << store::FormatUtc(e.wall_time_ns) << " [" << e.kind << "]";
      if (e.generator_time_s) std::cout << " t=" << Num(*e.generator_time_s) << " s";
      std::cout << " " << e.message << "\n";
    }
  });
}

void AddInterchange(CLI::App& app) {
  auto* ix = GetOrAddSubcommand(app, "interchange", "Interchange folders (format version 1)");
  auto folder = std::make_shared<std::string>();
  auto skip_images = std::make_shared<bool>(false);
  auto* check = ix->add_subcommand("check", "Read a folder with full validation, print counts");
  check->add_option("FOLDER", *folder, "interchange folder")->required();
  check->add_flag("--skip-image-decode", *skip_images,
                  "only check that images exist (do not decode them)");
  check->callback([folder, skip_images] {
    try {
      const auto r = interchange::ReadRecording(*folder);
      if (!*skip_images) interchange::CheckImageFiles(*folder, r);
      std::cout << RecordingSummary(r) << "OK: " << *folder << " reads as msmcal-interchange/1\n";
    } catch (const interchange::InterchangeError& e) {
      throw std::runtime_error("in " + *folder + ": " + e.what());
    }
  });
}

void AddDataCommands(CLI::App& app) {
  AddImport(app);
  AddExport(app);
  AddSessions(app);
  AddInterchange(app);
}

}  // namespace

MSMCAL_REGISTER_COMMANDS(/*order=*/90, AddDataCommands);

}  // namespace msmcal::app
