#include "processing/hall/delta_t.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

namespace msmcal::hall {

std::string DeltaTIdentificationOptions::Validate() const {
  std::ostringstream s;
  if (edge_steps < 0)
    s << "edge_steps must be >= 0, got " << edge_steps;
  else if (!(min_split_agreement >= 0 && min_split_agreement <= 1))
    s << "min_split_agreement must be in [0, 1], got " << min_split_agreement;
  else if (!(min_separation >= 0))
    s << "min_separation must be >= 0, got " << min_separation;
  else if (!(max_sigma_s > 0))
    s << "max_sigma_s must be > 0, got " << max_sigma_s;
  else if (!(max_phase_disagreement_sigmas > 0))
    s << "max_phase_disagreement_sigmas must be > 0, got " << max_phase_disagreement_sigmas;
  return s.str();
}

const char* ToString(DeltaTMethod method) {
  return method == DeltaTMethod::kDrivePhases ? "drive phases" : "field model";
}

bool ParseDeltaTMethod(const std::string& text, DeltaTMethod* method) {
  for (DeltaTMethod m : {DeltaTMethod::kFieldModel, DeltaTMethod::kDrivePhases})
    if (text == ToString(m)) {
      *method = m;
      return true;
    }
  return false;
}

const char* ToString(DeltaTStatus status) {
  switch (status) {
    case DeltaTStatus::kIdentified:
      return "identified";
    case DeltaTStatus::kNoFastDrive:
      return "no fast drive";
    case DeltaTStatus::kNoFieldModel:
      return "no field model";
    case DeltaTStatus::kAtBound:
      return "at a bound";
    case DeltaTStatus::kSplitsDisagree:
      return "splits disagree";
    case DeltaTStatus::kImprecise:
      return "imprecise";
    case DeltaTStatus::kAmbiguous:
      return "ambiguous";
  }
  return "?";
}

bool ParseDeltaTStatus(const std::string& text, DeltaTStatus* status) {
  for (DeltaTStatus s :
       {DeltaTStatus::kIdentified, DeltaTStatus::kNoFastDrive, DeltaTStatus::kNoFieldModel,
        DeltaTStatus::kAtBound, DeltaTStatus::kSplitsDisagree, DeltaTStatus::kImprecise,
        DeltaTStatus::kAmbiguous})
    if (text == ToString(s)) {
      *status = s;
      return true;
    }
  return false;
}

std::string FormatMs(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f ms", s * 1e3);
  return buf;
}

namespace {

double StdDev(const std::vector<double>& v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  double mean = 0, ss = 0;
  for (double x : v) mean += x / v.size();
  for (double x : v) ss += (x - mean) * (x - mean) / v.size();
  return std::sqrt(ss);
}

}  // namespace

DeltaTEstimate IdentifyDeltaT(const DeltaTEvidence& e, const DeltaTIdentificationOptions& o) {
  if (const std::string msg = o.Validate(); !msg.empty())
    throw std::invalid_argument("DeltaTIdentificationOptions: " + msg);
  const DeltaTProfile& p = e.profile;
  if (p.dt_s.size() < 3 || p.cost.size() != p.dt_s.size())
    throw std::invalid_argument("IdentifyDeltaT: the profile needs at least 3 grid points");
  DeltaTEstimate r;
  r.model = p.kind;
  r.delta_t_s = e.final_delta_t_s;
  r.search_min_s = e.search_min_s;
  r.search_max_s = e.search_max_s;
  r.bracket_min_s = e.bracket_min_s;
  r.bracket_max_s = e.bracket_max_s;
  const size_t n = p.cost.size();
  const size_t g =
      static_cast<size_t>(std::min_element(p.cost.begin(), p.cost.end()) - p.cost.begin());
  r.profile_min_s = p.dt_s[g];
  if (!(e.fast_frequency_hz > 0)) {
    r.status = DeltaTStatus::kNoFastDrive;
    r.reason =
        "the fast drive frequency is unknown: dt is seen only through the fast drive's phase";
    return r;
  }
  const double step = p.dt_s[1] - p.dt_s[0];
  const double edge = o.edge_steps * step + 1e-12;
  const double valley = 0.125 / e.fast_frequency_hz;  // half width of a valley: 1/8 fast period

  // The splits: how many find dt in the minimum's valley; the spread of those that do.
  std::vector<double> agreeing, bracketed;
  for (double dt : e.split_delta_t_s)
    if (std::abs(dt - r.profile_min_s) < valley) agreeing.push_back(dt);
  for (double dt : e.bracketed_split_delta_t_s)
    if (std::abs(dt - r.profile_min_s) < valley) bracketed.push_back(dt);
  r.splits = static_cast<int>(e.split_delta_t_s.size());
  r.splits_agreeing = static_cast<int>(agreeing.size());
  r.sigma_s = StdDev(bracketed.empty() ? agreeing : bracketed);

  // The other valleys: local minima of the grid (the ends included) away from the minimum.
  const double sigma2 =
      std::max(p.cost[g] / std::max(1, p.residual_dof), std::numeric_limits<double>::min());
  for (size_t i = 0; i < n; ++i) {
    const bool left = i == 0 || p.cost[i] <= p.cost[i - 1];
    const bool right = i + 1 == n || p.cost[i] <= p.cost[i + 1];
    if (!left || !right || std::abs(p.dt_s[i] - r.profile_min_s) <= valley) continue;
    const double sep = (p.cost[i] - p.cost[g]) / sigma2;
    if (std::isnan(r.separation) || sep < r.separation) {
      r.separation = sep;
      r.runner_up_s = p.dt_s[i];
    }
  }

  // 2. Inside the window and the bracket, and the final fit in the profile's valley.
  if (r.profile_min_s <= r.search_min_s + edge || r.profile_min_s >= r.search_max_s - edge) {
    r.status = DeltaTStatus::kAtBound;
    const bool outside = r.profile_min_s < r.search_min_s || r.profile_min_s > r.search_max_s;
    r.reason =
        std::string(outside ? "the cost is lowest beyond the search window's bound, at "
                            : "the cost falls towards the search window's bound, minimum at ") +
        FormatMs(r.profile_min_s) + " (window " + FormatMs(r.search_min_s) + " .. " +
        FormatMs(r.search_max_s) + "): the true dt may lie beyond it";
    return r;
  }
  if (e.final_delta_t_s <= e.bracket_min_s + edge || e.final_delta_t_s >= e.bracket_max_s - edge) {
    r.status = DeltaTStatus::kAtBound;
    r.reason = "the final fit's dt " + FormatMs(e.final_delta_t_s) +
               " lies at its bracket's bound (" + FormatMs(e.bracket_min_s) + " .. " +
               FormatMs(e.bracket_max_s) + ")";
    return r;
  }
  if (std::abs(e.final_delta_t_s - r.profile_min_s) > 2 * step) {
    r.status = DeltaTStatus::kAmbiguous;
    r.reason = "the final fit's dt " + FormatMs(e.final_delta_t_s) + " (bracket " +
               FormatMs(e.bracket_min_s) + " .. " + FormatMs(e.bracket_max_s) +
               ") is not the whole window's minimum at " + FormatMs(r.profile_min_s);
    return r;
  }
  // 3. The splits agree.
  if (r.splits_agreeing < o.min_split_agreement * r.splits) {
    r.status = DeltaTStatus::kSplitsDisagree;
    r.reason = std::to_string(r.splits - r.splits_agreeing) + " of " + std::to_string(r.splits) +
               " train/test splits find dt more than " + FormatMs(valley) +
               " from the minimum at " + FormatMs(r.profile_min_s) + " (spread " +
               FormatMs(StdDev(e.split_delta_t_s)) +
               "): the data do not choose between the fast drive's valleys";
    return r;
  }
  // 4. The splits agree closely.
  if (!(r.sigma_s <= o.max_sigma_s)) {
    r.status = DeltaTStatus::kImprecise;
    r.reason = "the train/test splits' dt scatters by " + FormatMs(r.sigma_s) + " (at most " +
               FormatMs(o.max_sigma_s) + "): too few poses or readings to pin dt down";
    return r;
  }
  // 5. No other valley nearly as deep.
  if (r.separation < o.min_separation) {
    char buf[64], need[32];
    std::snprintf(buf, sizeof buf, "%.1f", r.separation);
    std::snprintf(need, sizeof need, "%g", o.min_separation);
    r.status = DeltaTStatus::kAmbiguous;
    r.reason = "another minimum at " + FormatMs(r.runner_up_s) + " costs only " + buf +
               " residual variances more than the one at " + FormatMs(r.profile_min_s) + " (need " +
               need + "): too few poses or readings to tell the fast drive's valleys apart";
    return r;
  }
  r.status = DeltaTStatus::kIdentified;
  return r;
}

}  // namespace msmcal::hall
