#include "sessions/store/transfer.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <set>
#include <sstream>

#include "sessions/interchange/interchange_io.h"

namespace msmcal::store {
namespace {

namespace fs = std::filesystem;

constexpr const char* kHallNames[] = {"actual", "background"};

std::string ReadFile(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw StoreError("cannot read " + p.string());
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void FsyncDir(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

std::string Normal(const std::string& rel) {
  return fs::path(rel).lexically_normal().generic_string();
}

bool IsTemporary(const fs::path& p) {
  const std::string name = p.filename().string();
  return name.size() > 1 && name[0] == '.' && name.find(".tmp-") != std::string::npos;
}

}  // namespace

std::unique_ptr<SessionStore> ImportInterchange(const fs::path& folder, const fs::path& session_dir,
                                                const Clock& clock, const ImportOptions& options) {
  std::error_code ec;
  if (fs::exists(session_dir, ec)) {
    throw StoreError("session " + session_dir.string() + ": already exists");
  }
  // Full validation first: nothing is created for a folder that does not read.
  const dataset::Recording rec = interchange::ReadRecording(folder);
  const std::string session_text = ReadFile(folder / "session.yaml");
  const std::string camera_text = ReadFile(folder / "camera.yaml");

  const fs::path parent = session_dir.has_parent_path() ? session_dir.parent_path() : fs::path(".");
  fs::create_directories(parent, ec);
  const fs::path staging =
      parent / ("." + session_dir.filename().string() + ".importing-" + std::to_string(::getpid()));
  fs::remove_all(staging, ec);
  try {
    SessionMetadata meta;
    meta.rig_id = options.rig_id;
    meta.mirror_id = options.mirror_id;
    meta.note = options.note;
    meta.description = rec;
    auto store = SessionStore::Create(staging, meta, clock);
    store->SetMeta("import.source", fs::absolute(folder).lexically_normal().string());
    store->SetMeta("import.session_yaml", session_text);
    store->SetMeta("import.camera_yaml", camera_text);
    store->SetTriggers(rec.triggers);

    std::set<std::string> known = {"session.yaml", "camera.yaml"};
    auto copy_image = [&](const std::string& file) {
      interchange::WriteFileAtomically(staging / file, ReadFile(folder / file));
      known.insert(Normal(file));
    };
    for (const auto& f : rec.step1) {
      copy_image(f.file);
      FrameRecord r;
      r.step = "step1";
      r.file = f.file;
      r.pose = f.pose;
      r.beams = f.beams;
      store->AddFrameRecord(r);
    }
    for (const auto& f : rec.step2) {
      copy_image(f.file);
      FrameRecord r;
      r.step = "step2";
      r.file = f.file;
      r.kind = f.kind;
      r.triggers = f.triggers;
      r.beams = f.beams;
      store->AddFrameRecord(r);
    }
    for (const char* name : kHallNames) {
      const auto& hall = std::string(name) == "actual" ? rec.hall_actual : rec.hall_background;
      if (!hall) continue;
      store->SetMeta(std::string("hall.") + name + ".present", "1");
      store->AppendHallReadings(name, hall->readings);
      store->AppendClockEdges(name, hall->clock_edges_us);
      known.insert(std::string("hall/") + name + ".csv");
      known.insert(std::string("hall/") + name + "_clock.csv");
    }
    // Everything else (marg/, truth/, results/, notes) verbatim.
    for (auto it = fs::recursive_directory_iterator(folder);
         it != fs::recursive_directory_iterator(); ++it) {
      if (!it->is_regular_file() || IsTemporary(it->path())) continue;
      const std::string rel = fs::relative(it->path(), folder).generic_string();
      if (known.count(rel)) continue;
      if (rel.rfind("results/", 0) == 0) {
        store->PutResult(rel.substr(8), ReadFile(it->path()));
      } else {
        store->PutAttachment(rel, ReadFile(it->path()));
      }
    }
    store->SetStep("import", StepState::kDone);
    store->AddEvent("import", "imported from " + fs::absolute(folder).lexically_normal().string());
    store.reset();
    fs::rename(staging, session_dir);
    FsyncDir(parent);
  } catch (...) {
    fs::remove_all(staging, ec);
    throw;
  }
  return SessionStore::Open(session_dir, clock);
}

void PutResultsFromFolder(SessionStore& store, const fs::path& results_dir) {
  std::error_code ec;
  if (!fs::is_directory(results_dir, ec)) {
    throw StoreError("results folder " + results_dir.string() + " does not exist");
  }
  for (auto it = fs::recursive_directory_iterator(results_dir);
       it != fs::recursive_directory_iterator(); ++it) {
    if (!it->is_regular_file() || IsTemporary(it->path())) continue;
    store.PutResult(fs::relative(it->path(), results_dir).generic_string(), ReadFile(it->path()));
  }
}

dataset::Recording RecordingFromStore(const SessionStore& store) {
  dataset::Recording r = store.Description();
  r.triggers = store.Triggers();
  for (const auto& f : store.Frames()) {
    if (!f.accepted) continue;
    if (f.step == "step1") {
      r.step1.push_back({f.file, f.pose, f.beams});
    } else {
      r.step2.push_back({f.file, f.kind, f.triggers, f.beams});
    }
  }
  const std::vector<std::string> names = store.HallRecordingNames();
  for (const char* name : kHallNames) {
    const bool present = store.GetMeta(std::string("hall.") + name + ".present").has_value() ||
                         std::find(names.begin(), names.end(), name) != names.end();
    if (!present) continue;
    dataset::HallRecording hall;
    hall.readings = store.HallReadings(name);
    hall.clock_edges_us = store.ClockEdges(name);
    (std::string(name) == "actual" ? r.hall_actual : r.hall_background) = std::move(hall);
  }
  return r;
}

void ExportInterchange(const SessionStore& store, const fs::path& folder) {
  std::error_code ec;
  if (fs::exists(folder, ec) && !fs::is_empty(folder, ec)) {
    throw StoreError("export folder " + folder.string() + " exists and is not empty");
  }
  const dataset::Recording r = RecordingFromStore(store);
  const std::string camera_problem = r.camera.Validate();
  if (!camera_problem.empty()) {
    throw StoreError("session " + store.dir().string() + ": no usable camera model to export (" +
                     camera_problem + ")");
  }
  const std::string problem = interchange::CheckRecording(r);
  if (!problem.empty()) {
    throw StoreError("session " + store.dir().string() + ": inconsistent: " + problem);
  }
  fs::create_directories(folder);
  for (const auto& f : r.step1) {
    interchange::WriteFileAtomically(folder / f.file, ReadFile(store.dir() / f.file));
  }
  for (const auto& f : r.step2) {
    interchange::WriteFileAtomically(folder / f.file, ReadFile(store.dir() / f.file));
  }
  for (const auto& path : store.AttachmentPaths()) {
    interchange::WriteFileAtomically(folder / path, *store.GetAttachment(path));
  }
  for (const auto& name : store.ResultNames()) {
    interchange::WriteFileAtomically(folder / "results" / name, *store.GetResult(name));
  }
  if (r.hall_actual) {
    interchange::WriteHallCsv(folder / "hall/actual.csv", folder / "hall/actual_clock.csv",
                              *r.hall_actual);
  }
  if (r.hall_background) {
    interchange::WriteHallCsv(folder / "hall/background.csv", folder / "hall/background_clock.csv",
                              *r.hall_background);
  }
  // The imported texts verbatim while they still say what the session holds, else ours.
  std::string camera_text = interchange::FormatCameraYaml(r.camera);
  if (const auto verbatim = store.GetMeta("import.camera_yaml")) {
    try {
      if (interchange::FormatCameraYaml(interchange::ParseCameraYaml(*verbatim, "camera.yaml")) ==
          camera_text) {
        camera_text = *verbatim;
      }
    } catch (const interchange::InterchangeError&) {
    }
  }
  std::string session_text = interchange::FormatSessionYaml(r);
  if (const auto verbatim = store.GetMeta("import.session_yaml")) {
    try {
      dataset::Recording original;
      interchange::ParseSessionYaml(*verbatim, "session.yaml", &original);
      if (interchange::FormatSessionYaml(original) == session_text) session_text = *verbatim;
    } catch (const interchange::InterchangeError&) {
    }
  }
  interchange::WriteFileAtomically(folder / "camera.yaml", camera_text);
  // session.yaml last: a folder with a session.yaml is complete.
  interchange::WriteFileAtomically(folder / "session.yaml", session_text);
}

}  // namespace msmcal::store
