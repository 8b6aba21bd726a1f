#pragma once
// Import and export between the interchange folder (../shared/docs/interchange-format.md) and
// the session store. Lossless: exporting an imported session reproduces session.yaml and
// camera.yaml byte for byte (kept verbatim unless the session's data changed since), the hall/
// CSVs value for value (byte for byte when msmcal wrote them), images, marg/, truth/ and
// results/ byte for byte.

#include <filesystem>
#include <memory>
#include <string>

#include "sessions/store/session_store.h"

namespace msmcal::store {

struct ImportOptions {
  std::string rig_id;
  std::string mirror_id;
  std::string note;
};

// Reads `folder` with full validation (interchange::ReadRecording; throws InterchangeError
// naming file, line and field), then builds the session in a hidden staging folder beside
// `session_dir` and renames it into place, so that `session_dir` appears complete or not at
// all. `session_dir` must not exist.
std::unique_ptr<SessionStore> ImportInterchange(const std::filesystem::path& folder,
                                                const std::filesystem::path& session_dir,
                                                const Clock& clock,
                                                const ImportOptions& options = {});

// Writes the session as an interchange folder. `folder` must not exist or be empty. Only
// accepted frames are exported. Throws StoreError if the session has no camera model.
void ExportInterchange(const SessionStore& store, const std::filesystem::path& folder);

// Stores every file under `results_dir` (e.g. the results/ folder `msmcal solve` wrote) as
// results, by path relative to `results_dir`, replacing results of the same name.
void PutResultsFromFolder(SessionStore& store, const std::filesystem::path& results_dir);

// The interchange Recording the session holds (what ExportInterchange writes, without files
// kept verbatim).
dataset::Recording RecordingFromStore(const SessionStore& store);

}  // namespace msmcal::store
