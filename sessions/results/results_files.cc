#include "sessions/results/results_files.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "common/csv_writer.h"
#include "common/text_io.h"
#include "common/units.h"
#include "common/yaml_fields.h"
#include "processing/solver/mle.h"
#include "sessions/interchange/csv_reader.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::results {

namespace fs = std::filesystem;

namespace {

constexpr const char* kMirrorPlanesHeader =
    "j,t_s,nx,ny,nz,d_mm,alpha_deg,beta_deg,trans_mm,sigma_alpha_deg,sigma_beta_deg,"
    "sigma_trans_mm";
constexpr const char* kBeamsHeader = "beam,px,py,pz,vx,vy,vz";
constexpr const char* kValidationHeader = "beam,j,err_px,err_deg";
constexpr const char* kValidationDetailHeader =
    "beam,j,err_px,err_deg,baseline_err_px,baseline_err_deg,predicted_sigma_px,normalised_error";
constexpr const char* kValidationDotsHeader =
    "beam,j,observed_x_px,observed_y_px,predicted_x_px,predicted_y_px,cov_xx_px2,cov_xy_px2,"
    "cov_yy_px2,joint_whitened_1,joint_whitened_2";
constexpr const char* kResidualsHeader =
    "family,group,observed_x_px,observed_y_px,whitened_1,whitened_2";
constexpr const char* kHallPosesHeader = "mcu_time_us,t_s,alpha_deg,beta_deg,trans_mm";

}  // namespace

namespace {

std::vector<dataset::MirrorPlaneRow> MirrorPlaneRows(interchange::CsvReader& csv) {
  std::vector<dataset::MirrorPlaneRow> rows;
  while (csv.Next()) {
    dataset::MirrorPlaneRow r;
    r.j = csv.Int(0);
    r.t_s = csv.Double(1);
    r.plane_in_world.n = Eigen::Vector3d(csv.Double(2), csv.Double(3), csv.Double(4));
    r.plane_in_world.d = csv.Double(5);
    r.alpha_deg = csv.Double(6);
    r.beta_deg = csv.Double(7);
    r.trans_mm = csv.Double(8);
    r.sigma_alpha_deg = csv.Double(9);
    r.sigma_beta_deg = csv.Double(10);
    r.sigma_trans_mm = csv.Double(11);
    rows.push_back(r);
  }
  return rows;
}

std::vector<dataset::BeamRow> BeamRows(interchange::CsvReader& csv) {
  std::vector<dataset::BeamRow> rows;
  while (csv.Next()) {
    dataset::BeamRow r;
    r.beam = csv.Int(0);
    r.p = Eigen::Vector3d(csv.Double(1), csv.Double(2), csv.Double(3));
    r.v = Eigen::Vector3d(csv.Double(4), csv.Double(5), csv.Double(6));
    rows.push_back(r);
  }
  return rows;
}

std::vector<dataset::ValidationRow> ValidationRows(interchange::CsvReader& csv) {
  std::vector<dataset::ValidationRow> rows;
  while (csv.Next()) {
    dataset::ValidationRow r;
    r.beam = csv.Int(0);
    r.j = csv.Int(1);
    r.err_px = csv.Double(2);
    r.err_deg = csv.Double(3);
    rows.push_back(r);
  }
  return rows;
}

}  // namespace

std::vector<dataset::MirrorPlaneRow> ReadMirrorPlanesCsv(const fs::path& file) {
  interchange::CsvReader csv(file, file.string(), {kMirrorPlanesHeader});
  return MirrorPlaneRows(csv);
}

std::vector<dataset::MirrorPlaneRow> ParseMirrorPlanesCsv(const std::string& text,
                                                          const std::string& display_name) {
  interchange::CsvReader csv(interchange::CsvReader::Text{text}, display_name,
                             {kMirrorPlanesHeader});
  return MirrorPlaneRows(csv);
}

std::string FormatMirrorPlanesCsv(const std::vector<dataset::MirrorPlaneRow>& rows) {
  std::string out = std::string(kMirrorPlanesHeader) + "\n";
  for (const auto& r : rows) {
    const auto& n = r.plane_in_world.n;
    common::AppendCsvRow(&out, r.j, r.t_s, n.x(), n.y(), n.z(), r.plane_in_world.d, r.alpha_deg,
                         r.beta_deg, r.trans_mm, r.sigma_alpha_deg, r.sigma_beta_deg,
                         r.sigma_trans_mm);
  }
  return out;
}

void WriteMirrorPlanesCsv(const fs::path& file, const std::vector<dataset::MirrorPlaneRow>& rows) {
  common::WriteFileAtomically(file, FormatMirrorPlanesCsv(rows));
}

std::vector<dataset::BeamRow> ReadBeamsCsv(const fs::path& file) {
  interchange::CsvReader csv(file, file.string(), {kBeamsHeader});
  return BeamRows(csv);
}

std::vector<dataset::BeamRow> ParseBeamsCsv(const std::string& text,
                                            const std::string& display_name) {
  interchange::CsvReader csv(interchange::CsvReader::Text{text}, display_name, {kBeamsHeader});
  return BeamRows(csv);
}

std::string FormatBeamsCsv(const std::vector<dataset::BeamRow>& rows) {
  std::string out = std::string(kBeamsHeader) + "\n";
  for (const auto& r : rows)
    common::AppendCsvRow(&out, r.beam, r.p.x(), r.p.y(), r.p.z(), r.v.x(), r.v.y(), r.v.z());
  return out;
}

void WriteBeamsCsv(const fs::path& file, const std::vector<dataset::BeamRow>& rows) {
  common::WriteFileAtomically(file, FormatBeamsCsv(rows));
}

std::vector<dataset::ValidationRow> ReadValidationCsv(const fs::path& file) {
  interchange::CsvReader csv(file, file.string(), {kValidationHeader});
  return ValidationRows(csv);
}

std::vector<dataset::ValidationRow> ParseValidationCsv(const std::string& text,
                                                       const std::string& display_name) {
  interchange::CsvReader csv(interchange::CsvReader::Text{text}, display_name, {kValidationHeader});
  return ValidationRows(csv);
}

std::string FormatValidationCsv(const std::vector<dataset::ValidationRow>& rows) {
  std::string out = std::string(kValidationHeader) + "\n";
  for (const auto& r : rows) common::AppendCsvRow(&out, r.beam, r.j, r.err_px, r.err_deg);
  return out;
}

void WriteValidationCsv(const fs::path& file, const std::vector<dataset::ValidationRow>& rows) {
  common::WriteFileAtomically(file, FormatValidationCsv(rows));
}

std::vector<ValidationDetailRow> ValidationDetailRows(
    const std::vector<solver::ValidationDetail>& validation) {
  std::vector<ValidationDetailRow> rows;
  for (const auto& v : validation)
    rows.push_back({v.row.beam, v.row.j, v.row.err_px, v.row.err_deg, v.baseline.err_px,
                    v.baseline.err_deg, v.predicted_sigma_px, v.normalised_error});
  return rows;
}

namespace {

std::vector<ValidationDetailRow> DetailRows(interchange::CsvReader& csv) {
  std::vector<ValidationDetailRow> rows;
  while (csv.Next()) {
    rows.push_back({csv.Int(0), csv.Int(1), csv.Double(2), csv.Double(3), csv.Double(4),
                    csv.Double(5), csv.Double(6), csv.Double(7)});
  }
  return rows;
}

std::vector<ValidationDotRow> DotRows(interchange::CsvReader& csv) {
  std::vector<ValidationDotRow> rows;
  while (csv.Next()) {
    ValidationDotRow r;
    r.beam = csv.Int(0);
    r.j = csv.Int(1);
    r.observed_px = {csv.Double(2), csv.Double(3)};
    r.predicted_px = {csv.Double(4), csv.Double(5)};
    // Every cell read before the comma initializer: a cell that throws inside it would leave
    // Eigen's initializer incomplete, and its destructor asserts (an abort where assertions are
    // on, as in the fuzz build) instead of the error naming file, line and column.
    const double xx = csv.Double(6), xy = csv.Double(7), yy = csv.Double(8);
    r.cov_px2 << xx, xy, xy, yy;
    r.joint_whitened = {csv.Double(9), csv.Double(10)};
    rows.push_back(r);
  }
  return rows;
}

std::vector<solver::WhitenedResidual> ResidualRows(interchange::CsvReader& csv) {
  std::vector<solver::WhitenedResidual> rows;
  while (csv.Next()) {
    solver::WhitenedResidual r;
    r.family = csv.Int(0);
    if (r.family < 0 || r.family >= solver::kNumFamilies)
      throw interchange::InterchangeError(csv.display() + ":" + std::to_string(csv.line()) +
                                          ": column 'family': " + std::to_string(r.family) +
                                          " is not a residual family (0.." +
                                          std::to_string(solver::kNumFamilies - 1) + ")");
    r.group = csv.Int(1);
    r.observed_px = {csv.Double(2), csv.Double(3)};
    r.whitened = {csv.Double(4), csv.Double(5)};
    rows.push_back(r);
  }
  return rows;
}

std::vector<HallPoseRow> HallPoseRows(interchange::CsvReader& csv) {
  std::vector<HallPoseRow> rows;
  while (csv.Next())
    rows.push_back({csv.Double(0), csv.Double(1), csv.Double(2), csv.Double(3), csv.Double(4)});
  return rows;
}

}  // namespace

std::vector<ValidationDetailRow> ReadValidationDetailCsv(const fs::path& file) {
  interchange::CsvReader csv(file, file.string(), {kValidationDetailHeader});
  return DetailRows(csv);
}

std::vector<ValidationDetailRow> ParseValidationDetailCsv(const std::string& text,
                                                          const std::string& display_name) {
  interchange::CsvReader csv(interchange::CsvReader::Text{text}, display_name,
                             {kValidationDetailHeader});
  return DetailRows(csv);
}

std::string FormatValidationDetailCsv(const std::vector<ValidationDetailRow>& rows) {
  std::string out = std::string(kValidationDetailHeader) + "\n";
  for (const auto& r : rows)
    common::AppendCsvRow(&out, r.beam, r.j, r.err_px, r.err_deg, r.baseline_err_px,
                         r.baseline_err_deg, r.predicted_sigma_px, r.normalised_error);
  return out;
}

void WriteValidationDetailCsv(const fs::path& file, const std::vector<ValidationDetailRow>& rows) {
  common::WriteFileAtomically(file, FormatValidationDetailCsv(rows));
}

std::vector<ValidationDotRow> ValidationDotRows(
    const std::vector<solver::ValidationDetail>& validation) {
  std::vector<ValidationDotRow> rows;
  for (const auto& v : validation)
    rows.push_back(
        {v.row.beam, v.row.j, v.observed_px, v.predicted_px, v.cov_px2, v.joint_whitened});
  return rows;
}

std::vector<ValidationDotRow> ReadValidationDotsCsv(const fs::path& file) {
  interchange::CsvReader csv(file, file.string(), {kValidationDotsHeader});
  return DotRows(csv);
}

std::vector<ValidationDotRow> ParseValidationDotsCsv(const std::string& text,
                                                     const std::string& display_name) {
  interchange::CsvReader csv(interchange::CsvReader::Text{text}, display_name,
                             {kValidationDotsHeader});
  return DotRows(csv);
}

std::string FormatValidationDotsCsv(const std::vector<ValidationDotRow>& rows) {
  std::string out = std::string(kValidationDotsHeader) + "\n";
  for (const auto& r : rows)
    common::AppendCsvRow(&out, r.beam, r.j, r.observed_px.x(), r.observed_px.y(),
                         r.predicted_px.x(), r.predicted_px.y(), r.cov_px2(0, 0), r.cov_px2(0, 1),
                         r.cov_px2(1, 1), r.joint_whitened.x(), r.joint_whitened.y());
  return out;
}

void WriteValidationDotsCsv(const fs::path& file, const std::vector<ValidationDotRow>& rows) {
  common::WriteFileAtomically(file, FormatValidationDotsCsv(rows));
}

std::vector<solver::WhitenedResidual> ReadResidualsCsv(const fs::path& file) {
  interchange::CsvReader csv(file, file.string(), {kResidualsHeader});
  return ResidualRows(csv);
}

std::vector<solver::WhitenedResidual> ParseResidualsCsv(const std::string& text,
                                                        const std::string& display_name) {
  interchange::CsvReader csv(interchange::CsvReader::Text{text}, display_name, {kResidualsHeader});
  return ResidualRows(csv);
}

std::string FormatResidualsCsv(const std::vector<solver::WhitenedResidual>& rows) {
  std::string out = std::string(kResidualsHeader) + "\n";
  for (const auto& r : rows)
    common::AppendCsvRow(&out, r.family, r.group, r.observed_px.x(), r.observed_px.y(),
                         r.whitened.x(), r.whitened.y());
  return out;
}

void WriteResidualsCsv(const fs::path& file, const std::vector<solver::WhitenedResidual>& rows) {
  common::WriteFileAtomically(file, FormatResidualsCsv(rows));
}

std::vector<HallPoseRow> ReadHallPosesCsv(const fs::path& file) {
  interchange::CsvReader csv(file, file.string(), {kHallPosesHeader});
  return HallPoseRows(csv);
}

std::vector<HallPoseRow> ParseHallPosesCsv(const std::string& text,
                                           const std::string& display_name) {
  interchange::CsvReader csv(interchange::CsvReader::Text{text}, display_name, {kHallPosesHeader});
  return HallPoseRows(csv);
}

std::string FormatHallPosesCsv(const std::vector<HallPoseRow>& rows) {
  std::string out = std::string(kHallPosesHeader) + "\n";
  for (const auto& r : rows)
    common::AppendCsvRow(&out, r.mcu_time_us, r.t_s, r.alpha_deg, r.beta_deg, r.trans_mm);
  return out;
}

void WriteHallPosesCsv(const fs::path& file, const std::vector<HallPoseRow>& rows) {
  common::WriteFileAtomically(file, FormatHallPosesCsv(rows));
}

// ------------------------------------------------------------------------------ summary.json

MirrorPosesSummary SummariseSolve(const solver::SolveOutput& out, double solve_time_s) {
  MirrorPosesSummary s;
  s.solve_time_s = solve_time_s;
  s.ceres_time_s = out.mle.solver_time_s;
  s.ceres_iterations = out.mle.iterations;
  s.planes_scan = out.num_scan_planes;
  s.planes_fast_only = out.num_fast_only_planes;
  s.planes_neutral = out.num_neutral_planes;
  s.beams = static_cast<int>(out.beams.size());
  s.mean_spanning_angle_deg = out.mean_spanning_angle_deg;
  s.validation_rms_deg = out.rms_validation_deg;
  s.validation_rms_px = out.rms_validation_px;
  s.baseline_validation_rms_deg = out.rms_baseline_deg;
  s.baseline_validation_rms_px = out.rms_baseline_px;
  s.validation_normalised_rms = out.rms_normalised_validation;
  s.validation_count = static_cast<int>(out.validation.size());
  s.corner_variance_factor = out.mle.corner_variance_factor;
  s.dot_variance_factor = out.mle.dot_variance_factor;
  for (int f = 0; f < solver::kNumFamilies; ++f)
    s.variance_factors.push_back(
        {solver::MleFamilyName(f), out.mle.variance_factor[f], out.mle.redundancy[f]});
  const Eigen::Matrix<double, 6, 1> sd = out.mirror0_cov.diagonal().cwiseSqrt();
  s.mirror0_sigma_rotation_deg = sd.head<3>() * common::kDegPerRad;
  s.mirror0_sigma_origin_mm = sd.tail<3>();
  double sa = 0, sb = 0, st = 0;
  for (const auto& r : out.planes) {
    sa += r.sigma_alpha_deg * r.sigma_alpha_deg;
    sb += r.sigma_beta_deg * r.sigma_beta_deg;
    st += r.sigma_trans_mm * r.sigma_trans_mm;
  }
  const double n = std::max<double>(1, out.planes.size());
  s.rms_sigma_alpha_deg = std::sqrt(sa / n);
  s.rms_sigma_beta_deg = std::sqrt(sb / n);
  s.rms_sigma_trans_mm = std::sqrt(st / n);
  if (out.mle.usable) {
    // The beams the covariance holds, in order (NaN: not held, or not a number).
    for (size_t b = 0; b < out.beams.size(); ++b) {
      const double sigma = out.mle.BeamDirectionSigmaRad(static_cast<int>(b));
      if (!std::isfinite(sigma)) break;
      s.beam_direction_sigma_deg.push_back(sigma * common::kDegPerRad);
    }
    double sn = 0;
    for (const auto& c : out.mle.plane_cov) {
      const double sigma = solver::DirectionSigmaRad(c.topLeftCorner<2, 2>());
      sn += sigma * sigma;
    }
    if (!out.mle.plane_cov.empty()) {
      const double rms = std::sqrt(sn / static_cast<double>(out.mle.plane_cov.size()));
      if (std::isfinite(rms)) s.rms_sigma_normal_world_deg = rms * common::kDegPerRad;  // else -1
    }
  }
  s.dropped_frames = out.dropped;
  s.notes = out.notes;
  s.world_from_mirror0_rotation = out.world_from_mirror0.RotationMatrix();
  s.world_from_mirror0_translation = out.world_from_mirror0.translation;
  return s;
}

namespace {

nlohmann::json Vec3Json(const Eigen::Vector3d& v) { return {v(0), v(1), v(2)}; }

nlohmann::json SummaryJson(const MirrorPosesSummary& s) {
  nlohmann::json j;
  j["solve_time_s"] = s.solve_time_s;
  j["ceres_time_s"] = s.ceres_time_s;
  j["ceres_iterations"] = s.ceres_iterations;
  j["planes_scan"] = s.planes_scan;
  j["planes_fast_only"] = s.planes_fast_only;
  j["planes_neutral"] = s.planes_neutral;
  j["beams"] = s.beams;
  j["mean_spanning_angle_deg"] = s.mean_spanning_angle_deg;
  j["validation_rms_deg"] = s.validation_rms_deg;
  j["validation_rms_px"] = s.validation_rms_px;
  j["baseline_validation_rms_deg"] = s.baseline_validation_rms_deg;
  j["baseline_validation_rms_px"] = s.baseline_validation_rms_px;
  j["validation_normalised_rms"] = s.validation_normalised_rms;
  j["validation_count"] = s.validation_count;
  j["corner_variance_factor"] = s.corner_variance_factor;
  j["dot_variance_factor"] = s.dot_variance_factor;
  nlohmann::json fam = nlohmann::json::object();
  for (const auto& f : s.variance_factors)
    fam[f.name] = {{"variance_factor", f.variance_factor}, {"redundancy", f.redundancy}};
  j["variance_factors"] = fam;
  j["mirror0_sigma"] = {{"rotation_deg", Vec3Json(s.mirror0_sigma_rotation_deg)},
                        {"origin_mm", Vec3Json(s.mirror0_sigma_origin_mm)}};
  j["rms_sigma_alpha_deg"] = s.rms_sigma_alpha_deg;
  j["rms_sigma_beta_deg"] = s.rms_sigma_beta_deg;
  j["rms_sigma_trans_mm"] = s.rms_sigma_trans_mm;
  j["beam_direction_sigma_deg"] = s.beam_direction_sigma_deg;
  j["rms_sigma_normal_world_deg"] = s.rms_sigma_normal_world_deg;
  nlohmann::json dropped = nlohmann::json::array();
  for (const auto& d : s.dropped_frames)
    dropped.push_back({{"file", d.file}, {"reason", d.reason}});
  j["dropped_frames"] = dropped;
  j["notes"] = s.notes;
  const Eigen::Matrix3d& r = s.world_from_mirror0_rotation;
  j["world_from_mirror0"] = {
      {"R", {r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1), r(1, 2), r(2, 0), r(2, 1), r(2, 2)}},
      {"t", Vec3Json(s.world_from_mirror0_translation)}};
  return j;
}

// Strict access to the parsed summary: every miss names the file and the key path.
class JsonFields {
 public:
  explicit JsonFields(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void Fail(const std::string& path, const std::string& what) const {
    throw interchange::InterchangeError(file_ + ": " + path + ": " + what);
  }
  const nlohmann::json& Get(const nlohmann::json& parent, const std::string& path,
                            const std::string& key) const {
    if (!parent.is_object() || !parent.contains(key)) Fail(path + key, "missing");
    return parent.at(key);
  }
  double Number(const nlohmann::json& parent, const std::string& path,
                const std::string& key) const {
    return AsNumber(Get(parent, path, key), path + key);
  }
  double AsNumber(const nlohmann::json& v, const std::string& path) const {
    if (v.is_null()) return std::nan("");  // how nlohmann writes a non-finite number
    if (!v.is_number()) Fail(path, "expected a number, got " + v.dump());
    return v.get<double>();
  }
  int Integer(const nlohmann::json& parent, const std::string& path, const std::string& key) const {
    const nlohmann::json& v = Get(parent, path, key);
    if (!v.is_number_integer()) Fail(path + key, "expected an integer, got " + v.dump());
    return v.get<int>();
  }
  std::string String(const nlohmann::json& v, const std::string& path) const {
    if (!v.is_string()) Fail(path, "expected a string, got " + v.dump());
    return v.get<std::string>();
  }
  const nlohmann::json& Array(const nlohmann::json& parent, const std::string& path,
                              const std::string& key, size_t size = 0) const {
    const nlohmann::json& v = Get(parent, path, key);
    if (!v.is_array() || (size > 0 && v.size() != size))
      Fail(path + key,
           size > 0 ? "expected " + std::to_string(size) + " numbers" : "expected a list");
    return v;
  }
  Eigen::Vector3d Vec3(const nlohmann::json& parent, const std::string& path,
                       const std::string& key) const {
    const nlohmann::json& v = Array(parent, path, key, 3);
    Eigen::Vector3d out;
    for (int k = 0; k < 3; ++k) out(k) = AsNumber(v[k], path + key + "[" + std::to_string(k) + "]");
    return out;
  }

 private:
  std::string file_;
};

}  // namespace

void UpdateSummaryJson(const fs::path& file, const std::string& key, nlohmann::json value) {
  nlohmann::json all = nlohmann::json::object();
  if (fs::exists(file)) {
    std::ifstream in(file);
    try {
      all = nlohmann::json::parse(in);
    } catch (const std::exception&) {
      all = nlohmann::json::object();
    }
    if (!all.is_object()) all = nlohmann::json::object();
  }
  all[key] = std::move(value);
  // Unchanged content is not rewritten: a sweep's resume compares results/ by mtime too.
  const std::string text = all.dump(2) + "\n";
  if (fs::exists(file)) {
    std::ifstream in(file, std::ios::binary);
    std::ostringstream old;
    old << in.rdbuf();
    if (old.str() == text) return;
  }
  common::WriteFileAtomically(file, text);
}

void WriteMirrorPosesSummary(const fs::path& file, const MirrorPosesSummary& summary) {
  UpdateSummaryJson(file, "mirror_poses", SummaryJson(summary));
}

void WriteHallSummary(const fs::path& file, const hall::HallCalibrationResult& r, size_t poses) {
  const hall::DeltaTEstimate& dt = r.delta_t;
  auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
  auto outputs = [](const Eigen::Vector3d& v) {
    return nlohmann::json{{"alpha_deg", v[0]}, {"beta_deg", v[1]}, {"trans_mm", v[2]}};
  };
  nlohmann::json j;
  j["model"] = hall::ToString(r.final_fit.model.kind);
  j["poses"] = poses;
  for (const auto& s : r.table)
    if (s.kind == r.final_fit.model.kind) {
      j["test_rms"] = outputs(s.test_rms_mean);
      j["test_rms_std"] = outputs(s.test_rms_std);
    }
  j["train_rms"] = outputs(r.final_fit.train_rms);
  j["model_delta_t_s"] = number(r.final_fit.model.delta_t_s);
  j["delta_t_identified"] = dt.identified();
  j["delta_t_status"] = hall::ToString(dt.status);
  j["delta_t_method"] = hall::ToString(dt.method);
  j["delta_t_model"] = hall::ToString(dt.model);
  j["delta_t_s"] = dt.identified() ? number(dt.delta_t_s) : nlohmann::json();
  j["delta_t_sigma_s"] = dt.identified() ? number(dt.sigma_s) : nlohmann::json();
  j["delta_t_profile_min_s"] = number(dt.profile_min_s);
  j["delta_t_reason"] = dt.reason;
  j["delta_t_bracket_from"] = hall::ToString(r.bracket);
  j["delta_t_drive_phase_s"] =
      r.drive_phase.determined ? number(r.drive_phase.delta_t_s) : nlohmann::json();
  j["delta_t_drive_phase_sigma_s"] =
      r.drive_phase.determined ? number(r.drive_phase.sigma_s) : nlohmann::json();
  j["delta_t_drive_phase_reason"] = r.drive_phase.reason;
  j["actual_readings_used"] = r.actual_periods.readings_used;
  UpdateSummaryJson(file, "hall", std::move(j));
}

bool SummaryJsonHas(const fs::path& file, const std::string& section) {
  if (!fs::exists(file)) return false;
  const JsonFields f(file.string());
  std::ifstream in(file);
  if (!in) f.Fail("(file)", "cannot open");
  nlohmann::json all;
  try {
    all = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    f.Fail("(file)", std::string("not JSON: ") + e.what());
  }
  if (!all.is_object()) f.Fail("(file)", "expected a JSON object");
  return all.contains(section);
}

MirrorPosesSummary ReadMirrorPosesSummary(const fs::path& file) {
  const JsonFields f(file.string());
  std::ifstream in(file);
  if (!in) f.Fail("(file)", "cannot open");
  nlohmann::json all;
  try {
    all = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    f.Fail("(file)", std::string("not JSON: ") + e.what());
  }
  const std::string p = "mirror_poses.";
  const nlohmann::json& j = f.Get(all, "", "mirror_poses");
  MirrorPosesSummary s;
  s.solve_time_s = f.Number(j, p, "solve_time_s");
  s.ceres_time_s = f.Number(j, p, "ceres_time_s");
  s.ceres_iterations = f.Integer(j, p, "ceres_iterations");
  s.planes_scan = f.Integer(j, p, "planes_scan");
  s.planes_fast_only = f.Integer(j, p, "planes_fast_only");
  s.planes_neutral = f.Integer(j, p, "planes_neutral");
  s.beams = f.Integer(j, p, "beams");
  s.mean_spanning_angle_deg = f.Number(j, p, "mean_spanning_angle_deg");
  s.validation_rms_deg = f.Number(j, p, "validation_rms_deg");
  s.validation_rms_px = f.Number(j, p, "validation_rms_px");
  s.baseline_validation_rms_deg = f.Number(j, p, "baseline_validation_rms_deg");
  s.baseline_validation_rms_px = f.Number(j, p, "baseline_validation_rms_px");
  s.validation_normalised_rms = f.Number(j, p, "validation_normalised_rms");
  s.validation_count = f.Integer(j, p, "validation_count");
  s.corner_variance_factor = f.Number(j, p, "corner_variance_factor");
  s.dot_variance_factor = f.Number(j, p, "dot_variance_factor");
  const nlohmann::json& fam = f.Get(j, p, "variance_factors");
  if (!fam.is_object()) f.Fail(p + "variance_factors", "expected an object");
  for (const auto& [name, v] : fam.items()) {
    const std::string q = p + "variance_factors." + name + ".";
    s.variance_factors.push_back(
        {name, f.Number(v, q, "variance_factor"), f.Number(v, q, "redundancy")});
  }
  const nlohmann::json& sigma = f.Get(j, p, "mirror0_sigma");
  s.mirror0_sigma_rotation_deg = f.Vec3(sigma, p + "mirror0_sigma.", "rotation_deg");
  s.mirror0_sigma_origin_mm = f.Vec3(sigma, p + "mirror0_sigma.", "origin_mm");
  s.rms_sigma_alpha_deg = f.Number(j, p, "rms_sigma_alpha_deg");
  s.rms_sigma_beta_deg = f.Number(j, p, "rms_sigma_beta_deg");
  s.rms_sigma_trans_mm = f.Number(j, p, "rms_sigma_trans_mm");
  if (j.contains("beam_direction_sigma_deg")) {  // written since session 24
    const nlohmann::json& bs = f.Array(j, p, "beam_direction_sigma_deg");
    for (size_t i = 0; i < bs.size(); ++i)
      s.beam_direction_sigma_deg.push_back(
          f.AsNumber(bs[i], p + "beam_direction_sigma_deg[" + std::to_string(i) + "]"));
  }
  if (j.contains("rms_sigma_normal_world_deg"))
    s.rms_sigma_normal_world_deg = f.Number(j, p, "rms_sigma_normal_world_deg");
  const nlohmann::json& dropped = f.Array(j, p, "dropped_frames");
  for (size_t i = 0; i < dropped.size(); ++i) {
    const std::string q = p + "dropped_frames[" + std::to_string(i) + "].";
    s.dropped_frames.push_back({f.String(f.Get(dropped[i], q, "file"), q + "file"),
                                f.String(f.Get(dropped[i], q, "reason"), q + "reason")});
  }
  const nlohmann::json& notes = f.Array(j, p, "notes");
  for (size_t i = 0; i < notes.size(); ++i)
    s.notes.push_back(f.String(notes[i], p + "notes[" + std::to_string(i) + "]"));
  const nlohmann::json& pose = f.Get(j, p, "world_from_mirror0");
  const nlohmann::json& r = f.Array(pose, p + "world_from_mirror0.", "R", 9);
  for (int k = 0; k < 9; ++k)
    s.world_from_mirror0_rotation(k / 3, k % 3) =
        f.AsNumber(r[k], p + "world_from_mirror0.R[" + std::to_string(k) + "]");
  s.world_from_mirror0_translation = f.Vec3(pose, p + "world_from_mirror0.", "t");
  return s;
}

// --------------------------------------------------------------------------- hall_model.yaml

namespace {

YAML::Node Vec(const Eigen::Vector3d& v) {
  YAML::Node n(YAML::NodeType::Sequence);
  for (int k = 0; k < 3; ++k) n.push_back(common::ShortestDouble(v[k]));
  n.SetStyle(YAML::EmitterStyle::Flow);
  return n;
}

YAML::Node Outputs(const Eigen::Vector3d& v) {
  YAML::Node n;
  n["alpha_deg"] = common::ShortestDouble(v[0]);
  n["beta_deg"] = common::ShortestDouble(v[1]);
  n["trans_mm"] = common::ShortestDouble(v[2]);
  n.SetStyle(YAML::EmitterStyle::Flow);
  return n;
}

}  // namespace

std::string FormatHallModelYaml(const hall::HallCalibrationResult& r,
                                const hall::HallCalibrationOptions& o) {
  const hall::HallModel& m = r.final_fit.model;
  YAML::Node y;
  y["format"] = "msmcal-hall-model/1";
  y["model"] = hall::ToString(m.kind);
  y["delta_t_s"] = common::ShortestDouble(m.delta_t_s);
  // The window that dt was searched in (the whole window, a bracket, or the judged field
  // model's valley for a sine model: HallCalibrationResult::final_min_s).
  y["delta_t_search_s"] = YAML::Node(YAML::NodeType::Sequence);
  y["delta_t_search_s"].push_back(common::ShortestDouble(r.final_min_s));
  y["delta_t_search_s"].push_back(common::ShortestDouble(r.final_max_s));
  y["delta_t_search_s"].SetStyle(YAML::EmitterStyle::Flow);
  y["outputs"] = YAML::Load("[alpha_deg, beta_deg, trans_mm]");
  YAML::Node params;
  YAML::Node a(YAML::NodeType::Sequence);
  for (int i = 0; i < m.a.rows(); ++i) {
    YAML::Node row(YAML::NodeType::Sequence);
    for (int j = 0; j < m.a.cols(); ++j) row.push_back(common::ShortestDouble(m.a(i, j)));
    row.SetStyle(YAML::EmitterStyle::Flow);
    a.push_back(row);
  }
  params["A"] = a;
  params["field_scale_uT"] = common::ShortestDouble(m.field_scale_uT);
  params["sine_frequency_hz"] = Vec(m.sine_frequency_hz);
  params["sine_phase_rad"] = Vec(m.sine_phase_rad);
  y["parameters"] = params;
  const hall::ModelStats* best = nullptr;
  for (const auto& s : r.table)
    if (s.kind == m.kind) best = &s;
  y["train_rms"] = Outputs(r.final_fit.train_rms);
  if (best) {
    y["test_rms"] = Outputs(best->test_rms_mean);
    y["test_rms_std"] = Outputs(best->test_rms_std);
  }
  YAML::Node cmp(YAML::NodeType::Sequence);
  for (const auto& s : r.table) {
    YAML::Node e;
    e["model"] = hall::ToString(s.kind);
    e["test_rms"] = Outputs(s.test_rms_mean);
    e["test_rms_std"] = Outputs(s.test_rms_std);
    e["train_rms"] = Outputs(s.train_rms_mean);
    e["delta_t_s"] = common::ShortestDouble(s.delta_t_mean_s);
    e["delta_t_std_s"] = common::ShortestDouble(s.delta_t_std_s);
    cmp.push_back(e);
  }
  y["comparison"] = cmp;
  // The session's dt: written as a figure only when the recording determines it.
  const hall::DeltaTEstimate& dt = r.delta_t;
  YAML::Node to;
  to["identified"] = dt.identified();
  to["status"] = hall::ToString(dt.status);
  to["method"] = hall::ToString(dt.method);
  to["model"] = hall::ToString(dt.model);
  if (dt.method == hall::DeltaTMethod::kDrivePhases) {
    to["field_status"] = hall::ToString(dt.field_status);
    to["field_reason"] = dt.field_reason;
  }
  auto number = [&to](const char* key, double v) {
    if (std::isfinite(v)) to[key] = common::ShortestDouble(v);
  };
  if (dt.identified()) {
    number("delta_t_s", dt.delta_t_s);
    number("sigma_s", dt.sigma_s);
  }
  if (!dt.reason.empty()) to["reason"] = dt.reason;
  number("profile_min_s", dt.profile_min_s);
  number("runner_up_s", dt.runner_up_s);
  number("separation", dt.separation);
  to["splits"] = dt.splits;
  to["splits_agreeing"] = dt.splits_agreeing;
  to["search_s"] = YAML::Node(YAML::NodeType::Sequence);
  to["search_s"].push_back(common::ShortestDouble(dt.search_min_s));
  to["search_s"].push_back(common::ShortestDouble(dt.search_max_s));
  to["search_s"].SetStyle(YAML::EmitterStyle::Flow);
  to["bracket_s"] = YAML::Node(YAML::NodeType::Sequence);
  to["bracket_s"].push_back(common::ShortestDouble(dt.bracket_min_s));
  to["bracket_s"].push_back(common::ShortestDouble(dt.bracket_max_s));
  to["bracket_s"].SetStyle(YAML::EmitterStyle::Flow);
  to["bracket_from"] = hall::ToString(r.bracket);
  // dt from the drives' phases (processing/hall/drive_phase.h): a witness independent of the
  // field models.
  const hall::DrivePhaseEstimate& ph = r.drive_phase;
  YAML::Node dp;
  dp["determined"] = ph.determined;
  dp["chooses_valley"] = ph.chooses_valley;
  auto dp_number = [&dp](const char* key, double v) {
    if (std::isfinite(v)) dp[key] = common::ShortestDouble(v);
  };
  dp_number("delta_t_s", ph.delta_t_s);
  dp_number("sigma_s", ph.sigma_s);
  dp_number("slow_delta_t_s", ph.slow.delta_t_s);
  dp_number("slow_sigma_s", ph.slow.sigma_s);
  dp_number("fast_delta_t_s", ph.fast.delta_t_s);
  dp_number("fast_coherence", ph.fast.coherence);
  dp_number("slow_coherence", ph.slow.coherence);
  dp_number("disagreement_sigmas", ph.disagreement_sigmas);
  dp_number("separation", ph.separation);
  if (!ph.reason.empty()) dp["reason"] = ph.reason;
  to["drive_phase"] = dp;
  y["time_offset"] = to;
  y["protocol"]["evaluation"] = r.leave_one_out ? "leave-one-out" : "random splits";
  y["protocol"]["repetitions"] = r.repetitions > 0 ? r.repetitions : o.repetitions;
  y["protocol"]["train_fraction"] = common::ShortestDouble(o.train_fraction);
  y["protocol"]["seed"] = o.seed;
  const hall::TimeBase& tb = r.actual_time_base;
  y["time_base"]["offset_us"] = common::ShortestDouble(tb.offset_us);
  y["time_base"]["rate_us_per_s"] = common::ShortestDouble(tb.rate_us_per_s);
  y["time_base"]["pattern_period_s"] = common::ShortestDouble(tb.pattern_period_s);
  y["time_base"]["jitter_rms_us"] = common::ShortestDouble(tb.jitter_rms_us);
  y["time_base"]["edges_used"] = tb.edges_used;
  y["time_base"]["edges_missing"] = tb.edges_missing;
  y["time_base"]["edges_rejected"] = tb.edges_rejected;
  y["actual_mean_uT"] = Vec(r.foreground.actual.Mean());
  YAML::Node bins(YAML::NodeType::Sequence);
  for (const auto& b : r.foreground.background.bins()) bins.push_back(Vec(b));
  y["background_profile"]["period_s"] = common::ShortestDouble(r.foreground.background.period_s());
  y["background_profile"]["bins_uT"] = bins;
  YAML::Emitter e;
  e << y;
  return std::string(e.c_str()) + "\n";
}

namespace {

[[noreturn]] void Fail(const std::string& file, const std::string& field, const std::string& what) {
  throw interchange::InterchangeError(file + ": field '" + field + "': " + what);
}

YAML::Node Need(const YAML::Node& n, const std::string& key, const std::string& file,
                const std::string& path) {
  if (!n.IsMap()) {
    Fail(file, path.empty() ? "(root)" : path.substr(0, path.size() - 1), "expected a mapping");
  }
  if (!n[key]) Fail(file, path + key, "missing");
  return n[key];
}

double Num(const YAML::Node& n, const std::string& file, const std::string& field) {
  try {
    return n.as<double>();
  } catch (const YAML::Exception&) {
    Fail(file, field, "expected a number (line " + std::to_string(common::YamlLine(n)) + ")");
  }
}

std::string Str(const YAML::Node& n, const std::string& file, const std::string& field) {
  if (!n.IsScalar()) {
    Fail(file, field, "expected a text (line " + std::to_string(common::YamlLine(n)) + ")");
  }
  return n.Scalar();
}

Eigen::Vector3d Vec3(const YAML::Node& n, const std::string& file, const std::string& field) {
  if (!n.IsSequence() || n.size() != 3) Fail(file, field, "expected a list of 3 numbers");
  return {Num(n[0], file, field), Num(n[1], file, field), Num(n[2], file, field)};
}

}  // namespace

HallModelFile ReadHallModelYaml(const fs::path& path) {
  const std::string file = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw interchange::InterchangeError(file + ": cannot open");
  std::ostringstream text;
  text << in.rdbuf();
  return ParseHallModelYaml(text.str(), file);
}

HallModelFile ParseHallModelYaml(const std::string& text, const std::string& file) {
  YAML::Node y;
  try {
    y = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw interchange::InterchangeError(file + ": " + e.what());
  }
  const std::string format = Str(Need(y, "format", file, ""), file, "format");
  if (format != "msmcal-hall-model/1")
    Fail(file, "format", "expected msmcal-hall-model/1, got '" + format + "'");
  HallModelFile l;
  const std::string kind = Str(Need(y, "model", file, ""), file, "model");
  if (!hall::ParseHallModelKind(kind, &l.model.kind))
    Fail(file, "model", "unknown model '" + kind + "'");
  l.model.delta_t_s = Num(Need(y, "delta_t_s", file, ""), file, "delta_t_s");
  const YAML::Node p = Need(y, "parameters", file, "");
  const YAML::Node a = Need(p, "A", file, "parameters.");
  const int f = l.model.FeatureCount();
  if (!a.IsSequence() || a.size() != 3) Fail(file, "parameters.A", "expected 3 rows");
  l.model.a.resize(3, f);
  for (int i = 0; i < 3; ++i) {
    if (!a[i].IsSequence() || static_cast<int>(a[i].size()) != f)
      Fail(file, "parameters.A",
           "row " + std::to_string(i) + " must have " + std::to_string(f) + " values for model " +
               kind);
    for (int j = 0; j < f; ++j) l.model.a(i, j) = Num(a[i][j], file, "parameters.A");
  }
  l.model.field_scale_uT =
      Num(Need(p, "field_scale_uT", file, "parameters."), file, "parameters.field_scale_uT");
  l.model.sine_frequency_hz =
      Vec3(Need(p, "sine_frequency_hz", file, "parameters."), file, "parameters.sine_frequency_hz");
  l.model.sine_phase_rad =
      Vec3(Need(p, "sine_phase_rad", file, "parameters."), file, "parameters.sine_phase_rad");
  const YAML::Node tb = Need(y, "time_base", file, "");
  l.time_base.offset_us =
      Num(Need(tb, "offset_us", file, "time_base."), file, "time_base.offset_us");
  l.time_base.rate_us_per_s =
      Num(Need(tb, "rate_us_per_s", file, "time_base."), file, "time_base.rate_us_per_s");
  l.time_base.pattern_period_s =
      Num(Need(tb, "pattern_period_s", file, "time_base."), file, "time_base.pattern_period_s");
  l.actual_mean_uT = Vec3(Need(y, "actual_mean_uT", file, ""), file, "actual_mean_uT");
  const YAML::Node bp = Need(y, "background_profile", file, "");
  const double period =
      Num(Need(bp, "period_s", file, "background_profile."), file, "background_profile.period_s");
  const YAML::Node bins = Need(bp, "bins_uT", file, "background_profile.");
  std::vector<Eigen::Vector3d> b;
  if (!bins.IsSequence()) Fail(file, "background_profile.bins_uT", "expected a list");
  for (const auto& n : bins) b.push_back(Vec3(n, file, "background_profile.bins_uT"));
  if (const YAML::Node tr = y["test_rms"]) {
    if (!tr.IsMap()) Fail(file, "test_rms", "expected a map of alpha_deg, beta_deg, trans_mm");
    l.test_rms =
        Eigen::Vector3d(Num(Need(tr, "alpha_deg", file, "test_rms."), file, "test_rms.alpha_deg"),
                        Num(Need(tr, "beta_deg", file, "test_rms."), file, "test_rms.beta_deg"),
                        Num(Need(tr, "trans_mm", file, "test_rms."), file, "test_rms.trans_mm"));
  }
  if (const YAML::Node to = y["time_offset"]) {
    if (!to.IsMap()) Fail(file, "time_offset", "expected a mapping");
    hall::DeltaTEstimate e;
    const std::string status =
        Str(Need(to, "status", file, "time_offset."), file, "time_offset.status");
    if (!hall::ParseDeltaTStatus(status, &e.status))
      Fail(file, "time_offset.status", "unknown status '" + status + "'");
    const std::string model =
        Str(Need(to, "model", file, "time_offset."), file, "time_offset.model");
    if (!hall::ParseHallModelKind(model, &e.model))
      Fail(file, "time_offset.model", "unknown model '" + model + "'");
    if (to["method"]) {  // files before the drives' phases: the field model
      const std::string method = Str(to["method"], file, "time_offset.method");
      if (!hall::ParseDeltaTMethod(method, &e.method))
        Fail(file, "time_offset.method", "unknown method '" + method + "'");
    }
    if (to["field_status"]) {
      const std::string fs = Str(to["field_status"], file, "time_offset.field_status");
      if (!hall::ParseDeltaTStatus(fs, &e.field_status))
        Fail(file, "time_offset.field_status", "unknown status '" + fs + "'");
    }
    if (to["field_reason"])
      e.field_reason = Str(to["field_reason"], file, "time_offset.field_reason");
    auto number = [&](const char* key, double* out) {
      if (to[key]) *out = Num(to[key], file, std::string("time_offset.") + key);
    };
    if (e.identified())
      e.delta_t_s = Num(Need(to, "delta_t_s", file, "time_offset."), file, "time_offset.delta_t_s");
    number("sigma_s", &e.sigma_s);
    number("profile_min_s", &e.profile_min_s);
    number("runner_up_s", &e.runner_up_s);
    number("separation", &e.separation);
    if (to["reason"]) e.reason = Str(to["reason"], file, "time_offset.reason");
    l.time_offset = e;
  }
  if (const YAML::Node p = y["protocol"]) {
    if (!p.IsMap()) Fail(file, "protocol", "expected a mapping");
    if (p["evaluation"]) {
      const std::string ev = Str(p["evaluation"], file, "protocol.evaluation");
      if (ev != "leave-one-out" && ev != "random splits")
        Fail(file, "protocol.evaluation",
             "expected 'random splits' or 'leave-one-out', got '" + ev + "'");
      l.leave_one_out = ev == "leave-one-out";
    }
    if (p["repetitions"]) {
      const double n = Num(p["repetitions"], file, "protocol.repetitions");
      if (!(n >= 1 && n <= 1e6 && n == std::floor(n)))
        Fail(file, "protocol.repetitions", "expected a whole number from 1 to 1000000");
      l.repetitions = static_cast<int>(n);
    }
  }
  try {
    l.background = hall::PhaseProfile::FromBins(period, std::move(b));
  } catch (const std::invalid_argument& e) {
    Fail(file, "background_profile", e.what());
  }
  return l;
}

}  // namespace msmcal::results
