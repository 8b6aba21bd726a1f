#include "sessions/sweep/sweep_summary.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "sessions/store/session_store.h"
#include "sessions/sweep/sweep_progress.h"

namespace msmcal::sweep {
namespace {

// The plan's file name of a journalled frame (rejected frames are stored under rejected/; the
// orchestrator's quality figures name the plan file).
std::string PlanFileOf(const store::FrameRecord& r) {
  try {
    const nlohmann::json q = nlohmann::json::parse(r.quality_json);
    if (q.contains("plan_file") && q["plan_file"].is_string()) return q["plan_file"];
  } catch (const nlohmann::json::exception&) {
  }
  return r.file;
}

namespace fs = std::filesystem;

std::optional<double> JsonNumber(const nlohmann::json& j, const char* key) {
  if (j.contains(key) && j[key].is_number()) return j[key].get<double>();
  return std::nullopt;
}

std::optional<double> YamlNumber(const YAML::Node& n) {
  if (!n || !n.IsScalar()) return std::nullopt;
  try {
    return n.as<double>();
  } catch (const YAML::Exception&) {
    return std::nullopt;
  }
}

std::string Fixed(const std::optional<double>& v, int digits) {
  if (!v) return "";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, *v);
  return buf;
}

std::string CsvCell(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string StatusText(const PointRecord& r) {
  if (r.status == PointStatus::kDone) return r.skipped_last_run ? "done (skipped)" : "done";
  return ToString(r.status);
}

struct Column {
  std::string header;
  std::vector<std::string> cells;
};

std::vector<Column> Columns(const SweepPlan& plan, const std::vector<SummaryRow>& rows,
                            bool for_csv) {
  std::vector<Column> cols;
  auto add = [&](const std::string& h, auto cell) {
    Column c{h, {}};
    for (const auto& r : rows) c.cells.push_back(cell(r));
    cols.push_back(std::move(c));
  };
  add("point", [](const SummaryRow& r) { return r.point.name; });
  for (size_t a = 0; a < plan.axes.size(); ++a)
    add(for_csv ? plan.axes[a].path : ShortAxisName(plan.axes[a].path), [a](const SummaryRow& r) {
      return a < r.point.values.size() ? r.point.values[a].second : "";
    });
  add("repeat", [](const SummaryRow& r) { return std::to_string(r.point.repeat); });
  add("seed", [](const SummaryRow& r) { return std::to_string(r.point.seed); });
  add("status", [](const SummaryRow& r) { return StatusText(r.record); });
  if (for_csv) add("reason", [](const SummaryRow& r) { return r.record.reason; });
  add(for_csv ? "frames_accepted" : "ok",
      [](const SummaryRow& r) { return std::to_string(r.figures.frames_accepted); });
  add(for_csv ? "frames_rejected" : "rej",
      [](const SummaryRow& r) { return std::to_string(r.figures.frames_rejected); });
  add(for_csv ? "hall_lost" : "lost", [](const SummaryRow& r) {
    return r.figures.hall_lost ? std::to_string(*r.figures.hall_lost) : std::string();
  });
  add(for_csv ? "validation_rms_deg" : "val_deg",
      [](const SummaryRow& r) { return Fixed(r.figures.validation_rms_deg, 5); });
  add(for_csv ? "validation_rms_px" : "val_px",
      [](const SummaryRow& r) { return Fixed(r.figures.validation_rms_px, 3); });
  add(for_csv ? "baseline_rms_deg" : "base_deg",
      [](const SummaryRow& r) { return Fixed(r.figures.baseline_rms_deg, 5); });
  add(for_csv ? "normal_rms_vs_truth_deg" : "n_true_deg",
      [](const SummaryRow& r) { return Fixed(r.figures.normal_rms_vs_truth_deg, 5); });
  add(for_csv ? "hall_model" : "hall", [](const SummaryRow& r) { return r.figures.hall_model; });
  add(for_csv ? "hall_rms_alpha_deg" : "h_a_deg",
      [](const SummaryRow& r) { return Fixed(r.figures.hall_rms_alpha_deg, 4); });
  add(for_csv ? "hall_rms_beta_deg" : "h_b_deg",
      [](const SummaryRow& r) { return Fixed(r.figures.hall_rms_beta_deg, 4); });
  add(for_csv ? "hall_rms_trans_mm" : "h_t_mm",
      [](const SummaryRow& r) { return Fixed(r.figures.hall_rms_trans_mm, 4); });
  // dt not identified by the recording: "n/i" in the table, an empty cell in the CSV.
  add(for_csv ? "hall_delta_t_ms" : "dt_ms", [for_csv](const SummaryRow& r) {
    if (r.figures.hall_delta_t_s) return Fixed(*r.figures.hall_delta_t_s * 1e3, 4);
    return r.figures.hall_delta_t_not_identified && !for_csv ? std::string("n/i") : std::string();
  });
  if (for_csv) {
    add("hall_vs_truth_alpha_deg",
        [](const SummaryRow& r) { return Fixed(r.figures.hall_vs_truth_alpha_deg, 4); });
    add("hall_vs_truth_beta_deg",
        [](const SummaryRow& r) { return Fixed(r.figures.hall_vs_truth_beta_deg, 4); });
    add("hall_vs_truth_trans_mm",
        [](const SummaryRow& r) { return Fixed(r.figures.hall_vs_truth_trans_mm, 4); });
  }
  add(for_csv ? "duration_s" : "time", [for_csv](const SummaryRow& r) {
    return for_csv ? Fixed(r.record.duration_s, 1) : FormatDuration(r.record.duration_s);
  });
  return cols;
}

}  // namespace

PointFigures ReadPointFigures(const fs::path& folder) {
  PointFigures f;
  // The journal's facts (never the log's text): the last decision per plan frame (a rejected
  // frame is journalled under rejected/), and the Hall readings the MCU reported lost.
  if (fs::exists(folder / store::kSessionDbName)) {
    try {
      const store::SystemClock clock;
      const auto journal = store::SessionStore::Open(folder, clock, /*read_only=*/true);
      std::map<std::string, bool> frames;  // plan file -> last decision
      for (const auto& r : journal->Frames()) frames[PlanFileOf(r)] = r.accepted;
      for (const auto& [file, ok] : frames) (ok ? f.frames_accepted : f.frames_rejected) += 1;
      for (const char* name : {"background", "actual"}) {
        const std::string key = std::string("hall.") + name + ".";
        if (!journal->GetMeta(key + "present")) continue;
        const auto lost = journal->GetMeta(key + "readings_lost");
        f.hall_lost = f.hall_lost.value_or(0) + (lost ? std::stoull(*lost) : 0);
      }
    } catch (const std::exception&) {  // an unreadable journal: no figures, as without one
    }
  }
  {
    std::ifstream in(folder / "results" / "summary.json");
    if (in) {
      try {
        const nlohmann::json j = nlohmann::json::parse(in);
        if (j.contains("mirror_poses") && j["mirror_poses"].is_object()) {
          const auto& m = j["mirror_poses"];
          f.validation_rms_deg = JsonNumber(m, "validation_rms_deg");
          f.validation_rms_px = JsonNumber(m, "validation_rms_px");
          f.baseline_rms_deg = JsonNumber(m, "baseline_validation_rms_deg");
        }
      } catch (const std::exception&) {
      }
    }
  }
  const fs::path hall_model = folder / "results" / "hall_model.yaml";
  if (fs::exists(hall_model)) {
    try {
      const YAML::Node y = YAML::LoadFile(hall_model.string());
      if (y["model"] && y["model"].IsScalar()) f.hall_model = y["model"].as<std::string>();
      const YAML::Node to = y["time_offset"];
      if (to && to.IsMap() && to["identified"] && to["identified"].IsScalar()) {
        if (to["identified"].as<bool>()) {
          f.hall_delta_t_s = YamlNumber(to["delta_t_s"]);
        } else {
          f.hall_delta_t_not_identified =
              to["reason"] && to["reason"].IsScalar() ? to["reason"].Scalar() : std::string();
        }
      } else {
        f.hall_delta_t_s = YamlNumber(y["delta_t_s"]);  // written before time_offset existed
      }
      YAML::Node rms = y["test_rms"] ? y["test_rms"] : y["train_rms"];
      if (rms && rms.IsMap()) {
        f.hall_rms_alpha_deg = YamlNumber(rms["alpha_deg"]);
        f.hall_rms_beta_deg = YamlNumber(rms["beta_deg"]);
        f.hall_rms_trans_mm = YamlNumber(rms["trans_mm"]);
      }
    } catch (const std::exception&) {
    }
  }
  return f;
}

std::string SummaryCsv(const SweepPlan& plan, const std::vector<SummaryRow>& rows) {
  const auto cols = Columns(plan, rows, /*for_csv=*/true);
  std::string out;
  for (size_t c = 0; c < cols.size(); ++c) out += (c ? "," : "") + CsvCell(cols[c].header);
  out += "\n";
  for (size_t r = 0; r < rows.size(); ++r) {
    for (size_t c = 0; c < cols.size(); ++c) out += (c ? "," : "") + CsvCell(cols[c].cells[r]);
    out += "\n";
  }
  return out;
}

std::string SummaryTable(const SweepPlan& plan, const std::vector<SummaryRow>& rows) {
  const auto cols = Columns(plan, rows, /*for_csv=*/false);
  std::vector<size_t> width(cols.size());
  for (size_t c = 0; c < cols.size(); ++c) {
    width[c] = cols[c].header.size();
    for (const auto& cell : cols[c].cells) width[c] = std::max(width[c], cell.size());
  }
  auto line = [&](auto cell_of) {
    std::string s;
    for (size_t c = 0; c < cols.size(); ++c) {
      std::string cell = cell_of(c);
      cell.resize(width[c], ' ');
      s += (c ? "  " : "") + cell;
    }
    while (!s.empty() && s.back() == ' ') s.pop_back();
    return s + "\n";
  };
  std::string out = line([&](size_t c) { return cols[c].header; });
  for (size_t r = 0; r < rows.size(); ++r) out += line([&](size_t c) { return cols[c].cells[r]; });
  size_t done = 0, failed = 0;
  for (const auto& r : rows) {
    if (r.record.status == PointStatus::kDone) ++done;
    if (r.record.status == PointStatus::kFailed) ++failed;
  }
  out += std::to_string(rows.size()) + " points: " + std::to_string(done) + " done, " +
         std::to_string(failed) + " failed, " + std::to_string(rows.size() - done - failed) +
         " not run\n";
  for (const auto& r : rows)
    if (r.record.status == PointStatus::kFailed)
      out += "  " + r.point.name + " failed: " + r.record.reason + "\n";
  return out;
}

}  // namespace msmcal::sweep
