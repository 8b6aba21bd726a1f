// Sweep mode (issue 9): plan parsing and its errors (file, line, key), point expansion and
// folder names, the resume decision, the state file, progress lines / ETA, the summary, and the
// runner over fake acquisition hooks (unattended failure handling, resume, plan mismatch).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <opencv2/core.hpp>
#include <set>
#include <sstream>
#include <string>

#include "drivers/generator/safe_state.h"
#include "sessions/store/session_store.h"
#include "sessions/sweep/sweep_plan.h"
#include "sessions/sweep/sweep_progress.h"
#include "sessions/sweep/sweep_runner.h"
#include "sessions/sweep/sweep_state.h"
#include "sessions/sweep/sweep_summary.h"
#include "simulation/sweep_points/sim_sweep_parameters.h"

namespace msmcal::sweep {
namespace {

namespace fs = std::filesystem;
using orchestrator::SessionEvent;

// A session journal as the orchestrator leaves it: frames (plan file, accepted; a rejected frame
// is stored under rejected/ with its plan file in the quality figures) and the Hall recordings'
// lost counts. Adds to an existing journal (a resumed session); a plan file already journalled
// is not recorded again.
void JournalFrames(const fs::path& dir, const std::vector<std::pair<std::string, bool>>& frames,
                   const std::map<std::string, int>& hall_lost = {}) {
  const store::FakeClock clock(1'000'000'000, 1'000'000);
  std::unique_ptr<store::SessionStore> j = fs::exists(dir / store::kSessionDbName)
                                               ? store::SessionStore::Open(dir, clock)
                                               : store::SessionStore::Create(dir, {}, clock);
  std::set<std::string> have;
  for (const auto& r : j->Frames()) have.insert(r.file);
  for (const auto& [file, ok] : frames) {
    store::FrameRecord r;
    r.step = file.substr(0, 5);
    r.file = ok ? file : "rejected/" + r.step + "_" + file.substr(6);
    if (have.count(r.file)) continue;
    r.accepted = ok;
    r.quality_json = "{\"plan_file\": \"" + file + "\"}";
    j->AddFrame(r, cv::Mat(2, 2, CV_8UC1, cv::Scalar(0)));
  }
  for (const auto& [name, lost] : hall_lost) {
    j->SetMeta("hall." + name + ".present", "1");
    j->SetMeta("hall." + name + ".readings_lost", std::to_string(lost));
  }
}

SessionEvent FrameEvent(int step, size_t index, size_t count, bool accepted) {
  SessionEvent e;
  e.kind = SessionEvent::Kind::kFrameDecided;
  e.step = step;
  e.index = index;
  e.count = count;
  e.accepted = accepted;
  return e;
}

// Plans over the simulator's options, as `msmcal sweep` reads them.
SweepPlan ParseSimPlan(const std::string& text, const std::string& source, const fs::path& dir) {
  return ParseSweepPlan(text, source, dir, simulation::SimSweepParameters());
}
SweepPlan LoadSimPlan(const fs::path& file) {
  return LoadSweepPlan(file, simulation::SimSweepParameters());
}

fs::path FreshDir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("sweep_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void WriteText(const fs::path& f, const std::string& text) {
  fs::create_directories(f.parent_path());
  std::ofstream(f) << text;
}

std::string ReadText(const fs::path& f) {
  std::ifstream in(f);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

const char* kPlan = R"(note: two by two
base:
  seed: 10
  step1:
    poses: 4
axes:
  mirror.fast.frequency_hz: [200, 205]
  triggers.max_triggers: [18, 30]
repeats: 2
)";

// Expects ParseSweepPlan(text) to throw with a message containing every part.
void ExpectPlanError(const std::string& text, const std::vector<std::string>& parts) {
  try {
    (void)ParseSimPlan(text, "plan.yaml", ".");
    ADD_FAILURE() << "no error for:\n" << text;
  } catch (const std::runtime_error& e) {
    const std::string msg = e.what();
    for (const auto& p : parts)
      EXPECT_NE(msg.find(p), std::string::npos) << msg << "\n  lacks: " << p;
  }
}

TEST(SweepPlan, ExpandsTheProductTimesRepeatsInnermostFastest) {
  const SweepPlan plan = ParseSimPlan(kPlan, "plan.yaml", ".");
  ASSERT_EQ(plan.axes.size(), 2u);
  EXPECT_EQ(plan.axes[0].line, 7);
  EXPECT_EQ(plan.repeats, 2);
  EXPECT_EQ(plan.note, "two by two");
  const auto points = ExpandPoints(plan);
  ASSERT_EQ(points.size(), 8u);
  // Default order: axes in file order, repeats innermost.
  EXPECT_EQ(points[0].name, "p001-fast.frequency_hz=200-triggers.max_triggers=18-r0");
  EXPECT_EQ(points[1].name, "p002-fast.frequency_hz=200-triggers.max_triggers=18-r1");
  EXPECT_EQ(points[2].name, "p003-fast.frequency_hz=200-triggers.max_triggers=30-r0");
  EXPECT_EQ(points[7].name, "p008-fast.frequency_hz=205-triggers.max_triggers=30-r1");
  EXPECT_EQ(points[1].Label(), "fast.frequency_hz=200 triggers.max_triggers=18 r1");
  std::set<std::string> names;
  for (const auto& p : points) {
    names.insert(p.name);
    EXPECT_EQ(simulation::PointSimOptions(p).step1.poses, 4);  // base applies to every point
    EXPECT_EQ(simulation::PointSimOptions(p).seed, 10u + static_cast<uint64_t>(p.repeat));
    EXPECT_EQ(p.seed, simulation::PointSimOptions(p).seed);  // what the summary's seed column shows
    EXPECT_DOUBLE_EQ(simulation::PointSimOptions(p).mirror.fast.frequency_hz,
                     std::stod(p.values[0].second));
    EXPECT_EQ(simulation::PointSimOptions(p).triggers.max_triggers, std::stoi(p.values[1].second));
    EXPECT_DOUBLE_EQ(simulation::PointSimOptions(p).mirror.slow.frequency_hz,
                     5.0);  // untouched default
  }
  EXPECT_EQ(names.size(), points.size());
}

TEST(SweepPlan, OrderPutsRepeatsOutermostAndReordersAxes) {
  std::string text = kPlan;
  text += "order: [repeats, triggers.max_triggers, mirror.fast.frequency_hz]\n";
  const auto points = ExpandPoints(ParseSimPlan(text, "plan.yaml", "."));
  ASSERT_EQ(points.size(), 8u);
  for (size_t i = 0; i < 4; ++i) EXPECT_EQ(points[i].repeat, 0);
  EXPECT_EQ(points[0].values[0].first, "triggers.max_triggers");  // values in nesting order
  EXPECT_EQ(points[1].values[1].second, "205");  // the innermost axis varies fastest
  EXPECT_EQ(points[2].values[0].second, "30");
  EXPECT_EQ(points[4].repeat, 1);
}

TEST(SweepPlan, ListValuedAxesAndBaseConfigRelativeToThePlan) {
  const fs::path dir = FreshDir("base_config");
  WriteText(dir / "cfg" / "tiny.yaml", "step1:\n  poses: 5\nseed: 7\n");
  WriteText(dir / "plan.yaml",
            "base_config: cfg/tiny.yaml\nbase:\n  seed: 8\naxes:\n"
            "  geometry.board_aim_mm: [[110, 135], [100, 140]]\n");
  const SweepPlan plan = LoadSimPlan(dir / "plan.yaml");
  const auto points = ExpandPoints(plan);
  ASSERT_EQ(points.size(), 2u);
  EXPECT_EQ(simulation::PointSimOptions(points[0]).step1.poses, 5);  // from base_config
  EXPECT_EQ(simulation::PointSimOptions(points[0]).seed, 8u);        // base: over base_config
  EXPECT_DOUBLE_EQ(simulation::PointSimOptions(points[1]).geometry.board_aim_mm[1], 140.0);
  EXPECT_EQ(points[1].name, "p002-geometry.board_aim_mm=100_140-r0");
}

TEST(SweepPlan, ErrorsNameTheFileTheLineAndTheKey) {
  ExpectPlanError("axes:\n  mirror.fast.frequency_hz: [200]\nrepeat: 2\n",
                  {"plan.yaml:3", "unknown key 'repeat'"});
  ExpectPlanError("axes:\n  mirror.fast.frequncy_hz: [200]\n",
                  {"plan.yaml:2", "axes.mirror.fast.frequncy_hz", "unknown simulator option"});
  ExpectPlanError("axes:\n  mirror.fast: [200]\n", {"plan.yaml:2", "axes.mirror.fast"});
  ExpectPlanError("axes:\n  mirror.fast.frequency_hz: [200, fast]\n",
                  {"plan.yaml:2", "axes.mirror.fast.frequency_hz", "expected a number"});
  ExpectPlanError("axes:\n  mirror.fast.frequency_hz: 200\n", {"plan.yaml:2", "non-empty list"});
  ExpectPlanError("base:\n  step1:\n    posez: 3\n",
                  {"plan.yaml:3", "base.step1.posez", "unknown simulator option"});
  ExpectPlanError("base:\n  render:\n    colour: 3\n", {"plan.yaml:3", "base.render.colour"});
  ExpectPlanError("repeats: 0\n", {"plan.yaml:1", "repeats", "out of range"});
  ExpectPlanError("axes:\n  seed: [1, 2]\n  step1.poses: [3]\norder: [seed]\n",
                  {"plan.yaml:4", "order", "step1.poses", "missing"});
  ExpectPlanError("axes:\n  seed: [1, 1]\n", {"plan.yaml:2", "axes.seed", "listed twice"});
  // A value the simulator refuses (Validate) names the axis and the field.
  ExpectPlanError("axes:\n  step1.poses: [3, -1]\n", {"plan.yaml:2", "step1.poses = -1"});
  ExpectPlanError("axes: [1, 2\n", {"plan.yaml:"});
  ExpectPlanError("base_config: missing.yaml\n", {"plan.yaml:1", "base_config", "missing.yaml"});
}

TEST(SweepPlan, TheDocumentedExamplePlanParses) {
  const char* env = std::getenv("MSMCAL_SOURCE_DIR");  // set by ctest
  const fs::path src = env ? fs::path(env) : fs::path(__FILE__).parent_path() / "../../..";
  const SweepPlan plan = LoadSimPlan(src / "config" / "sweep-example.yaml");
  const auto points = ExpandPoints(plan);
  EXPECT_EQ(points.size(), 16u);
  EXPECT_EQ(plan.repeat_level, 0u);
  EXPECT_EQ(points[8].repeat, 1);  // repeats outermost
  EXPECT_EQ(simulation::PointSimOptions(points[8]).seed, 2u);
}

TEST(SweepPlan, FolderNamesAreSanitisedAndBounded) {
  EXPECT_EQ(PointFolderName(2, 1, {{"a.b/c", "x y"}}), "p003-a.b_c=xy-r1");
  std::string long_value(300, '9');
  const std::string n = PointFolderName(41, 0, {{"step1.poses", long_value}});
  EXPECT_LE(n.size(), 120u);
  EXPECT_EQ(n.substr(0, 5), "p042-");
  EXPECT_EQ(n.substr(n.size() - 3), "-r0");
  EXPECT_EQ(ShortAxisName("mirror.fast.frequency_hz"), "fast.frequency_hz");
  EXPECT_EQ(ShortAxisName("seed"), "seed");
}

TEST(SweepPlan, SelfContainedCopyRoundTripsAndChangesAreNamed) {
  std::string text = kPlan;
  text += "order: [triggers.max_triggers, repeats, mirror.fast.frequency_hz]\n";
  const SweepPlan plan = ParseSimPlan(text, "plan.yaml", ".");
  const SweepPlan copy = ParseSimPlan(SweepPlanToYaml(plan), "sweep.yaml", "/nonexistent");
  EXPECT_EQ(ComparePlans(copy, plan), "");
  EXPECT_EQ(copy.repeat_level, 1u);
  EXPECT_EQ(copy.note, plan.note);

  std::string changed = text;
  changed.replace(changed.find("poses: 4"), 8, "poses: 5");
  const std::string diff = ComparePlans(copy, ParseSimPlan(changed, "new.yaml", "."));
  EXPECT_NE(diff.find("simulator options differ"), std::string::npos) << diff;
  EXPECT_NE(diff.find("poses"), std::string::npos) << diff;
  std::string more = text;
  more.replace(more.find("[18, 30]"), 8, "[18, 30, 40]");
  EXPECT_NE(ComparePlans(copy, ParseSimPlan(more, "new.yaml", ".")).find("12"), std::string::npos);
}

// Found by fuzz/sweep_yaml: a note ending in a bare CR (a CRLF file without its last LF) was
// written back bare and read back without it, so the plan's copy differed from the plan.
TEST(SweepPlan, NoteLineEndsAreTrimmedAndControlCharactersRefused) {
  const std::string text = "axes:\n  mirror.fast.frequency_hz: [205]\nrepeats: 2\nnote: x\r";
  const SweepPlan plan = ParseSimPlan(text, "plan.yaml", ".");
  EXPECT_EQ(plan.note, "x");
  const std::string written = SweepPlanToYaml(plan);
  EXPECT_EQ(SweepPlanToYaml(ParseSimPlan(written, "plan.yaml", ".")), written);
  const SweepPlan crlf = ParseSimPlan("note: two lines\r\nrepeats: 2\r\n", "plan.yaml", ".");
  EXPECT_EQ(crlf.note, "two lines");
  ExpectPlanError("repeats: 2\nnote: \"a\\rb\"\n",
                  {"plan.yaml:2", "note: control character 0x0d at byte 2"});
  ExpectPlanError("note: \"bell\\a\"\n", {"plan.yaml:1", "0x07"});
  ExpectPlanError(
      "note: a\xC2\x85"
      "b\n",
      {"plan.yaml:1", "control character 0x85 at byte 2"});
  // Not UTF-8 (found by fuzz/sweep_yaml: the copy wrote such bytes back as a control character).
  ExpectPlanError(
      "note: a\xC0\xC0"
      "b\n",
      {"plan.yaml:1", "not UTF-8 text at byte 2"});
  EXPECT_EQ(ParseSimPlan("note: Gr\xC3\xB6\xC3\x9F"
                         "e 5 \xC2\xB5"
                         "m\n",
                         "plan.yaml", ".")
                .note,
            "Gr\xC3\xB6\xC3\x9F"
            "e 5 \xC2\xB5"
            "m");
}

// Options with text fields (a rig file's host, camera kind): not varied by a sweep, but the
// plan's self-contained copy carries them (a rig sweep's DIR/sweep.yaml must read back).
class TextFieldParameters : public SweepParameters {
 public:
  std::string Noun() const override { return "rig file field"; }
  std::string PathHint() const override { return ""; }
  std::string DefaultsYaml() const override {
    return "unit1: {host: 127.0.0.1, port: 15025}\ncamera: {kind: gige, rate: 4}\n";
  }
  std::string LoadFile(const std::filesystem::path&) const override { return DefaultsYaml(); }
  std::string Resolve(const std::string& yaml, const std::string&, int repeat,
                      uint64_t* seed) const override {
    if (seed) *seed = static_cast<uint64_t>(repeat);
    return yaml;
  }
};

TEST(SweepPlan, TextFieldsAreCarriedByTheCopyButNeverVaried) {
  const auto params = std::make_shared<const TextFieldParameters>();
  const SweepPlan plan = ParseSweepPlan("axes: {camera.rate: [4, 8]}\n", "plan.yaml", ".", params);
  const SweepPlan copy = ParseSweepPlan(SweepPlanToYaml(plan), "sweep.yaml", ".", params);
  EXPECT_EQ(ComparePlans(copy, plan), "");
  try {
    (void)ParseSweepPlan("base: {unit1: {host: 10.0.0.2}}\naxes: {camera.rate: [4]}\n", "plan.yaml",
                         ".", params);
    ADD_FAILURE() << "a changed text field was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("plan.yaml:1: base.unit1.host: a text field"),
              std::string::npos)
        << e.what();
  }
}

TEST(SweepState, ResumeDecisionFollowsWhatIsOnDisk) {
  PointFolderState s;
  EXPECT_EQ(DecidePointAction(s), PointAction::kAcquire);  // absent
  s.folder_exists = true;
  EXPECT_EQ(DecidePointAction(s), PointAction::kAcquire);  // empty
  s.folder_empty = false;
  EXPECT_EQ(DecidePointAction(s), PointAction::kSetAside);  // files, no journal
  s.journal_exists = true;
  EXPECT_EQ(DecidePointAction(s), PointAction::kResume);  // killed mid-acquisition
  s.session_complete = true;
  EXPECT_EQ(DecidePointAction(s), PointAction::kFinish);  // killed while solving
  s.results_complete = true;
  EXPECT_EQ(DecidePointAction(s), PointAction::kSkip);
}

TEST(SweepState, RoundTripsAndNamesMalformedFields) {
  const fs::path dir = FreshDir("state");
  EXPECT_TRUE(ReadSweepState(dir / "absent.json").points.empty());
  SweepState s;
  s.points["p001"] = {PointStatus::kDone, "", 12.5, 1, false};
  s.points["p002"] = {PointStatus::kFailed, "camera: timeout, \"x\"", 3.0, 2, false};
  WriteSweepState(dir / "state.json", s);
  const SweepState r = ReadSweepState(dir / "state.json");
  ASSERT_EQ(r.points.size(), 2u);
  EXPECT_EQ(r.points.at("p002").status, PointStatus::kFailed);
  EXPECT_EQ(r.points.at("p002").reason, "camera: timeout, \"x\"");
  EXPECT_EQ(r.points.at("p002").attempts, 2);
  EXPECT_DOUBLE_EQ(r.points.at("p001").duration_s, 12.5);
  WriteText(dir / "bad.json", R"({"points": {"p001": {"status": "half"}}})");
  try {
    (void)ReadSweepState(dir / "bad.json");
    ADD_FAILURE();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("points.p001.status"), std::string::npos) << e.what();
  }
}

// A resumed session's figures come from its journal: one decision per plan frame, the Hall
// readings lost per recording (never from the log's text).
TEST(SweepProgress, PointFiguresComeFromTheJournal) {
  const fs::path dir = FreshDir("journal_figures");
  JournalFrames(dir, {{"step1/0000.png", true}, {"step1/0001.png", false}}, {{"background", 4}});
  JournalFrames(dir, {{"step1/0000.png", true}, {"step2/0000.png", true}},
                {{"background", 1}, {"actual", 2}});
  const PointFigures f = ReadPointFigures(dir);
  EXPECT_EQ(f.frames_accepted, 2u);
  EXPECT_EQ(f.frames_rejected, 1u);
  EXPECT_EQ(f.hall_lost.value_or(99), 3u);
  // No journal: no frame figures, no Hall figure.
  const PointFigures none = ReadPointFigures(FreshDir("no_journal"));
  EXPECT_EQ(none.frames_accepted + none.frames_rejected, 0u);
  EXPECT_FALSE(none.hall_lost.has_value());
}

TEST(SweepProgress, EtaAndTheProgressLine) {
  EXPECT_EQ(FormatDuration(42.4), "42 s");
  EXPECT_EQ(FormatDuration(185), "3:05");
  EXPECT_EQ(FormatDuration(3723), "1:02:03");
  EXPECT_EQ(FormatDuration(-1), "?");
  EtaEstimator eta;
  EXPECT_FALSE(eta.EtaSeconds(3, 0).has_value());
  eta.AddPointDuration(100);
  eta.AddPointDuration(200);
  EXPECT_DOUBLE_EQ(*eta.EtaSeconds(2, 50), 100.0 + 300.0);  // mean 150: 100 left + 2 x 150
  EXPECT_DOUBLE_EQ(*eta.EtaSeconds(0, 400), 0.0);
  EXPECT_DOUBLE_EQ(*eta.EtaSeconds(2, std::numeric_limits<double>::infinity()), 300.0);

  ProgressSnapshot s;
  s.point = 2;
  s.points = 4;
  s.label = "fast.frequency_hz=205 r0";
  s.step = "start";
  EXPECT_TRUE(ApplyEvent(FrameEvent(1, 2, 15, true), &s));
  SessionEvent step;
  step.kind = SessionEvent::Kind::kStepState;
  EXPECT_FALSE(ApplyEvent(step, &s));
  SessionEvent hall;
  hall.kind = SessionEvent::Kind::kHallDone;
  hall.recording = "background";
  hall.readings = 2000;
  hall.lost = 5;
  EXPECT_TRUE(ApplyEvent(hall, &s));
  EXPECT_EQ(s.step, "Hall background");
  EXPECT_EQ(s.event, "2000 readings");
  EXPECT_TRUE(ApplyEvent(FrameEvent(2, 0, 8, true), &s));
  s.elapsed_s = 83;
  s.eta_s = 130;
  EXPECT_EQ(FormatProgressLine(s),
            "sweep 2/4 [fast.frequency_hz=205 r0] step 2 frame 1/8 accepted | frames 2 ok 0 "
            "rejected | lost 5 | elapsed 1:23 | ETA 2:10");
  s.eta_s.reset();
  EXPECT_NE(FormatProgressLine(s).find("| ETA ?"), std::string::npos);
}

TEST(SweepSummary, ReadsFiguresAndWritesTheTable) {
  const fs::path dir = FreshDir("summary");
  JournalFrames(dir,
                {{"step1/0000.png", true}, {"step2/0000.png", true}, {"step2/0001.png", false}},
                {{"actual", 2}});
  WriteText(dir / "results" / "summary.json",
            R"({"mirror_poses": {"validation_rms_deg": 0.0123, "validation_rms_px": 0.5,
                "baseline_validation_rms_deg": 0.05}})");
  WriteText(dir / "results" / "hall_model.yaml",
            "format: msmcal-hall-model/1\nmodel: sine\ndelta_t_s: 0.00055\n"
            "test_rms: {alpha_deg: 0.08, beta_deg: 0.07, trans_mm: 0.1}\n");
  const PointFigures f = ReadPointFigures(dir);
  EXPECT_EQ(f.frames_accepted, 2u);
  EXPECT_EQ(f.frames_rejected, 1u);
  EXPECT_EQ(f.hall_lost.value_or(99), 2u);
  EXPECT_DOUBLE_EQ(f.validation_rms_deg.value_or(0), 0.0123);
  EXPECT_EQ(f.hall_model, "sine");
  EXPECT_DOUBLE_EQ(f.hall_delta_t_s.value_or(0), 0.00055);
  EXPECT_DOUBLE_EQ(f.hall_rms_beta_deg.value_or(0), 0.07);
  EXPECT_FALSE(ReadPointFigures(dir / "absent").validation_rms_deg.has_value());

  const SweepPlan plan =
      ParseSimPlan("axes:\n  mirror.fast.frequency_hz: [200, 205]\n", "plan.yaml", ".");
  const auto points = ExpandPoints(plan);
  std::vector<SummaryRow> rows = {
      {points[0], {PointStatus::kDone, "", 61, 1, false}, f},
      {points[1], {PointStatus::kFailed, "rig, \"bad\"", 5, 1, false}, {}}};
  const std::string csv = SummaryCsv(plan, rows);
  std::istringstream in(csv);
  std::string header, row1, row2;
  std::getline(in, header);
  std::getline(in, row1);
  std::getline(in, row2);
  EXPECT_EQ(header,
            "point,mirror.fast.frequency_hz,repeat,seed,status,reason,frames_accepted,"
            "frames_rejected,hall_lost,validation_rms_deg,validation_rms_px,baseline_rms_deg,"
            "normal_rms_vs_truth_deg,hall_model,hall_rms_alpha_deg,hall_rms_beta_deg,"
            "hall_rms_trans_mm,hall_delta_t_ms,hall_vs_truth_alpha_deg,hall_vs_truth_beta_deg,"
            "hall_vs_truth_trans_mm,duration_s");
  EXPECT_EQ(row1,
            "p001-fast.frequency_hz=200-r0,200,0,1,done,,2,1,2,0.01230,0.500,0.05000,,sine,0.0800,"
            "0.0700,0.1000,0.5500,,,,61.0");
  EXPECT_EQ(row2.substr(0, row2.find(",0,0,")),
            "p002-fast.frequency_hz=205-r0,205,0,1,failed,\"rig, \"\"bad\"\"\"");
  const std::string table = SummaryTable(plan, rows);
  EXPECT_NE(table.find("2 points: 1 done, 1 failed, 0 not run"), std::string::npos) << table;
  EXPECT_NE(table.find("p002-fast.frequency_hz=205-r0 failed: rig, \"bad\""), std::string::npos);
}

// hall_model.yaml's time_offset (issue 15): the session's dt when identified; when not, no figure
// (the model's own delta_t_s is not the session's): "n/i" in the table, an empty CSV cell.
TEST(SweepSummary, DeltaTNotIdentifiedIsShownInsteadOfANumber) {
  const fs::path dir = FreshDir("summary_dt");
  const std::string head = "format: msmcal-hall-model/1\nmodel: sine\ndelta_t_s: -0.0016\n";
  WriteText(dir / "results" / "hall_model.yaml",
            head +
                "time_offset: {identified: false, status: ambiguous, model: linear, reason: "
                "\"another minimum\"}\n");
  const PointFigures no = ReadPointFigures(dir);
  EXPECT_FALSE(no.hall_delta_t_s.has_value());
  EXPECT_EQ(no.hall_delta_t_not_identified.value_or("?"), "another minimum");
  const SweepPlan plan =
      ParseSimPlan("axes:\n  mirror.fast.frequency_hz: [205]\n", "plan.yaml", ".");
  const std::vector<SummaryRow> rows = {
      {ExpandPoints(plan)[0], {PointStatus::kDone, "", 61, 1, false}, no}};
  EXPECT_NE(SummaryTable(plan, rows).find("n/i"), std::string::npos) << SummaryTable(plan, rows);
  EXPECT_EQ(SummaryCsv(plan, rows).find("-1.6"), std::string::npos) << SummaryCsv(plan, rows);
  WriteText(dir / "results" / "hall_model.yaml",
            head +
                "time_offset: {identified: true, status: identified, model: cubic, delta_t_s: "
                "0.000548}\n");
  const PointFigures yes = ReadPointFigures(dir);
  EXPECT_DOUBLE_EQ(yes.hall_delta_t_s.value_or(0), 0.000548);
  EXPECT_FALSE(yes.hall_delta_t_not_identified.has_value());
}

// Fake rig for the runner: a point's "acquisition" writes a journal marker, a log and frames;
// "finish" writes results. Points can be told to fail.
struct FakeRig {
  double clock_s = 0;
  std::vector<std::string> printed;
  std::vector<std::string> calls;  // "acquire p001 resume=0", "finish p001"
  std::set<std::string> fail_acquire, fail_finish;
  std::set<std::string> unsafe_acquire;  // the safe state not confirmed (outputs may be on)

  SweepHooks Hooks() {
    SweepHooks h;
    h.now_s = [this] { return clock_s; };
    h.print = [this](const std::string& line, bool) { printed.push_back(line); };
    h.inspect = [](const fs::path& folder) {
      PointFolderState s;
      s.folder_exists = fs::exists(folder);
      s.folder_empty = !s.folder_exists || fs::is_empty(folder);
      s.journal_exists = fs::exists(folder / "session.db");
      s.session_complete = fs::exists(folder / "session.yaml");
      s.results_complete = fs::exists(folder / "results" / "summary.json");
      return s;
    };
    h.acquire = [this](const SweepPoint& p, const fs::path& folder, bool resume,
                       const orchestrator::SessionEventObserver& on_event) {
      calls.push_back("acquire " + p.name.substr(0, 4) + " resume=" + std::to_string(resume));
      for (size_t i = 0; i < 2; ++i) {
        JournalFrames(folder, {{"step1/000" + std::to_string(i) + ".png", true}});
        on_event(FrameEvent(1, i, 2, true));
        clock_s += 10;
      }
      if (unsafe_acquire.count(p.name.substr(0, 4)))
        throw gen::SafeStateNotConfirmed(75, "generator outputs NOT confirmed off");
      if (fail_acquire.count(p.name.substr(0, 4)))
        throw std::runtime_error(  // the orchestrator's rig check: a list of problems
            "rig check failed, not starting:\n  - Hall MCU: cannot open /dev/ttyACM0\n"
            "  - camera: no frame");
      WriteText(folder / "session.yaml", "complete");
    };
    h.finish = [this](const SweepPoint& p, const fs::path& folder) -> std::string {
      calls.push_back("finish " + p.name.substr(0, 4));
      clock_s += 5;
      if (fail_finish.count(p.name.substr(0, 4))) return "solve failed";
      WriteText(folder / "results" / "summary.json",
                R"({"mirror_poses": {"validation_rms_deg": 0.01}})");
      return "";
    };
    return h;
  }
};

// A point whose safe state is not confirmed stops the sweep (outputs may be on): no further
// point runs, the point is recorded as failed, the error reaches the command with its status.
TEST(SweepRunner, StopsWhenASafeStateIsNotConfirmed) {
  const fs::path dir = FreshDir("runner_unsafe") / "out";
  const SweepPlan plan =
      ParseSimPlan("axes:\n  triggers.max_triggers: [18, 24, 30]\n", "plan.yaml", ".");
  FakeRig rig;
  rig.unsafe_acquire = {"p002"};
  WriteText(dir / "sweep.yaml", SweepPlanToYaml(plan));
  try {
    RunSweep(plan, dir, rig.Hooks());
    FAIL() << "expected SafeStateNotConfirmed";
  } catch (const gen::SafeStateNotConfirmed& e) {
    EXPECT_EQ(e.exit_status(), 75);
  }
  EXPECT_EQ(rig.calls, (std::vector<std::string>{"acquire p001 resume=0", "finish p001",
                                                 "acquire p002 resume=0"}));
  const std::string state = ReadText(dir / "sweep_state.json");
  EXPECT_NE(state.find("NOT confirmed off"), std::string::npos) << state;
}

TEST(SweepRunner, GoesOnAfterAFailureAndResumesWithoutRedoingWork) {
  const fs::path dir = FreshDir("runner") / "out";
  const SweepPlan plan =
      ParseSimPlan("axes:\n  triggers.max_triggers: [18, 24, 30, 36]\n", "plan.yaml", ".");
  FakeRig rig;
  rig.fail_acquire = {"p002"};
  rig.fail_finish = {"p003"};
  // p004 was killed mid-acquisition by an earlier run: its journal exists, no session.yaml.
  const auto points = ExpandPoints(plan);
  JournalFrames(dir / points[3].name, {});
  WriteText(dir / "sweep.yaml", SweepPlanToYaml(plan));
  const SweepOutcome first = RunSweep(plan, dir, rig.Hooks());
  EXPECT_EQ(first.done, 2u);
  EXPECT_EQ(first.failed, 2u);
  EXPECT_EQ(rig.calls,
            (std::vector<std::string>{"acquire p001 resume=0", "finish p001",
                                      "acquire p002 resume=0", "acquire p003 resume=0",
                                      "finish p003", "acquire p004 resume=1", "finish p004"}));
  // The reason names every problem on one line (not just the list's heading).
  const std::string reason =
      "rig check failed, not starting: Hall MCU: cannot open /dev/ttyACM0; camera: no frame";
  EXPECT_EQ(first.rows[1].record.reason, reason);
  EXPECT_EQ(first.rows[2].record.reason, "solve failed");
  EXPECT_EQ(first.rows[0].figures.frames_accepted, 2u);
  EXPECT_DOUBLE_EQ(first.rows[0].record.duration_s, 25.0);
  // Progress lines: ETA unknown before the first finished point, then from its duration.
  bool saw_unknown = false, saw_eta = false;
  for (const auto& l : rig.printed) {
    if (l.find("sweep 1/4") == 0 && l.find("ETA ?") != std::string::npos) saw_unknown = true;
    if (l.find("sweep 2/4") == 0 && l.find("step 1 frame 1/2 accepted") != std::string::npos &&
        l.find("ETA") != std::string::npos && l.find("ETA ?") == std::string::npos)
      saw_eta = true;
  }
  EXPECT_TRUE(saw_unknown);
  EXPECT_TRUE(saw_eta);
  EXPECT_EQ(rig.printed.back().substr(0, 9), "sweep 4/4");
  EXPECT_NE(rig.printed.back().find("| ETA 0 s"), std::string::npos) << rig.printed.back();
  const std::string csv = ReadText(dir / "summary.csv");
  EXPECT_NE(csv.find("failed,\"" + reason + "\""), std::string::npos) << csv;

  // Second run: done points are skipped, the failed ones continue from what is on disk.
  rig.calls.clear();
  rig.fail_acquire.clear();
  rig.fail_finish.clear();
  const SweepOutcome second = RunSweep(plan, dir, rig.Hooks());
  EXPECT_EQ(second.done, 4u);
  EXPECT_EQ(rig.calls,
            (std::vector<std::string>{"acquire p002 resume=1", "finish p002", "finish p003"}));
  EXPECT_EQ(second.rows[0].record.attempts, 1);
  EXPECT_TRUE(second.rows[0].record.skipped_last_run);
  EXPECT_EQ(second.rows[1].record.attempts, 2);
  EXPECT_NE(second.table.find("4 points: 4 done, 0 failed"), std::string::npos);
  const SweepState state = ReadSweepState(dir / "sweep_state.json");
  EXPECT_EQ(state.points.at(points[2].name).status, PointStatus::kDone);
}

TEST(SweepRunner, RefusesAChangedPlanOrAForeignFolderAndSetsAsideJournalFreeFolders) {
  const fs::path base = FreshDir("runner_refuse");
  const SweepPlan plan = ParseSimPlan("axes:\n  seed: [1, 2]\n", "plan.yaml", ".");
  FakeRig rig;
  const auto points = ExpandPoints(plan);
  // A point folder with files but no journal (killed before the journal existed).
  WriteText(base / "a" / "sweep.yaml", SweepPlanToYaml(plan));
  WriteText(base / "a" / points[0].name / "session_log.txt", "[ 0.0 s] session started\n");
  (void)RunSweep(plan, base / "a", rig.Hooks());
  EXPECT_TRUE(fs::exists(base / "a" / (points[0].name + ".set-aside-1") / "session_log.txt"));
  EXPECT_TRUE(fs::exists(base / "a" / points[0].name / "results" / "summary.json"));

  const SweepPlan other = ParseSimPlan("axes:\n  seed: [1, 3]\n", "other.yaml", ".");
  try {
    (void)RunSweep(other, base / "a", rig.Hooks());
    ADD_FAILURE();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("holds a different sweep"), std::string::npos) << e.what();
  }
  WriteText(base / "b" / "x.txt", "x");
  EXPECT_THROW((void)RunSweep(plan, base / "b", rig.Hooks()), std::runtime_error);
}

}  // namespace
}  // namespace msmcal::sweep
