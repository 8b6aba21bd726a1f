#include "sessions/orchestrator/reference_steps.h"

#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <system_error>

#include "acquisition/hall/hall_csv_writer.h"
#include "sessions/interchange/interchange_io.h"
#include "sessions/store/session_store.h"

namespace msmcal::orchestrator {

namespace fs = std::filesystem;

namespace {

std::string Board(const dataset::BoardSpec& b) {
  return std::to_string(b.cols) + "x" + std::to_string(b.rows) + " squares of " +
         std::to_string(b.square_mm) + " mm";
}

std::string Beams(const std::vector<dataset::BeamSpec>& beams) {
  std::string s;
  for (const auto& b : beams)
    s += (s.empty() ? "" : ", ") + std::to_string(b.id) + " " + dataset::ToString(b.role);
  return "[" + s + "]";
}

// Hard-links `from` to `to` (a new name of the same bytes: images and readings are never
// rewritten in place), or copies when the two are on different file systems.
void LinkOrCopy(const fs::path& from, const fs::path& to) {
  if (!fs::exists(from)) throw std::runtime_error(from.string() + ": missing (reference session)");
  fs::create_directories(to.parent_path());
  std::error_code ec;
  fs::create_hard_link(from, to, ec);
  if (ec) fs::copy_file(from, to);
}

}  // namespace

dataset::Recording PlanWithReferenceStep1(const dataset::Recording& reference,
                                          const std::string& reference_name,
                                          const dataset::Recording& designed) {
  auto differ = [&](const std::string& field, const std::string& ref, const std::string& want) {
    throw std::runtime_error(reference_name + ": " + field + " = " + ref +
                             " differs from the rig file's " + want +
                             " (its step 1 frames are not of this rig)");
  };
  auto same_board = [](const dataset::BoardSpec& a, const dataset::BoardSpec& b) {
    return a.cols == b.cols && a.rows == b.rows && a.square_mm == b.square_mm;
  };
  if (!same_board(reference.world_board, designed.world_board))
    differ("boards.world", Board(reference.world_board), Board(designed.world_board));
  if (!same_board(reference.sliding_board, designed.sliding_board))
    differ("boards.sliding", Board(reference.sliding_board), Board(designed.sliding_board));
  bool same_beams = reference.beams.size() == designed.beams.size();
  for (size_t i = 0; same_beams && i < reference.beams.size(); ++i)
    same_beams = reference.beams[i].id == designed.beams[i].id &&
                 reference.beams[i].role == designed.beams[i].role;
  if (!same_beams) differ("beams", Beams(reference.beams), Beams(designed.beams));
  if (reference.camera.width != designed.camera.width ||
      reference.camera.height != designed.camera.height)
    differ("camera size",
           std::to_string(reference.camera.width) + "x" + std::to_string(reference.camera.height),
           std::to_string(designed.camera.width) + "x" + std::to_string(designed.camera.height));
  if (reference.step1.empty())
    throw std::runtime_error(reference_name + ": session.yaml lists no step 1 frame");
  dataset::Recording plan = designed;
  plan.camera = reference.camera;
  plan.step1 = reference.step1;
  plan.hall_actual.reset();
  plan.hall_background.reset();
  return plan;
}

void SeedSessionFromReference(const OrchestratorOptions& options, const dataset::Recording& plan,
                              const fs::path& reference_dir) {
  const fs::path out = options.out_dir;
  if (fs::exists(out) && !fs::is_empty(out))
    throw std::runtime_error(out.string() + ": session folder exists and is not empty");
  const fs::path background = reference_dir / "hall" / "background.csv";
  const fs::path background_clock = acquisition::ClockCsvPathFor(background);
  if (!fs::exists(background))
    throw std::runtime_error(background.string() +
                             ": missing (the reference's background Hall recording)");
  const fs::path staging = out.parent_path() / ("." + out.filename().string() + ".seeding");
  fs::remove_all(staging);  // a seed cut short by a kill
  const store::SystemClock system_clock;
  const store::Clock& clock = options.clock ? *options.clock : system_clock;
  {
    const std::unique_ptr<store::SessionStore> journal =
        CreateSessionJournal(options, plan, staging, clock);
    for (const auto& f : plan.step1) {
      LinkOrCopy(reference_dir / f.file, staging / f.file);
      store::FrameRecord record;
      record.step = "step1";
      record.file = f.file;
      record.pose = f.pose;
      record.beams = f.beams;
      record.accepted = true;
      record.quality_json =
          nlohmann::json{{"plan_file", f.file}, {"reference", reference_dir.string()}}.dump();
      journal->AddFrameRecord(record);
    }
    LinkOrCopy(background, staging / "hall" / "background.csv");
    if (fs::exists(background_clock))
      LinkOrCopy(background_clock, staging / "hall" / background_clock.filename());
    const dataset::HallRecording rec =
        interchange::ReadHallCsv(staging / "hall" / "background.csv",
                                 acquisition::ClockCsvPathFor(staging / "hall" / "background.csv"));
    journal->AppendHallReadings("background", rec.readings);
    journal->AppendClockEdges("background", rec.clock_edges_us);
    journal->SetMeta("hall.background.present", "1");
    // The reference's loss counts travel with its recording (the summary adds them up).
    std::string dropped = "0", lost = "0";
    if (fs::exists(reference_dir / store::kSessionDbName)) {
      const auto ref = store::SessionStore::Open(reference_dir, clock, /*read_only=*/true);
      dropped = ref->GetMeta("hall.background.readings_dropped").value_or("0");
      lost = ref->GetMeta("hall.background.readings_lost").value_or("0");
    }
    journal->SetMeta("hall.background.readings_dropped", dropped);
    journal->SetMeta("hall.background.readings_lost", lost);
    journal->SetStep(kStep1, store::StepState::kDone);
    journal->SetStep(kStepBackground, store::StepState::kDone);
    const std::string line = "step 1 (" + std::to_string(plan.step1.size()) +
                             " frames) and the background Hall recording (" +
                             std::to_string(rec.readings.size()) + " readings) taken from " +
                             reference_dir.string();
    journal->AddEvent("info", line);
    if (std::FILE* log = std::fopen((staging / "session_log.txt").c_str(), "w")) {
      std::fprintf(log, "[   0.000 s] %s\n", line.c_str());
      std::fclose(log);
    }
  }
  fs::rename(staging, out);  // an empty out_dir is replaced (rename(2))
}

}  // namespace msmcal::orchestrator
