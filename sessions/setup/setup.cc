#include "sessions/setup/setup.h"

#include <algorithm>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

namespace msmcal::setup {
namespace {

using nlohmann::json;

std::string JoinInts(const std::vector<int>& v) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) {
    if (i > 0) s += (i + 1 == v.size()) ? " and " : ", ";
    s += std::to_string(v[i]);
  }
  return s;
}

std::string Beams(const std::vector<int>& ids) {
  return (ids.size() == 1 ? "beam " : "beams ") + JoinInts(ids);
}

std::string Header(int number, int total, const std::string& title) {
  return "\n=== [" + std::to_string(number) + "/" + std::to_string(total) + "] " + title + " ===\n";
}

std::string Numbered(const std::vector<std::string>& items) {
  std::string s;
  for (size_t i = 0; i < items.size(); ++i)
    s += "  " + std::to_string(i + 1) + ". " + items[i] + "\n";
  return s;
}

// "unblock beams 1, 2 and 3 (all beams)" / "unblock beam 2 only; block beams 1 and 3 ...".
std::string BeamsLine(const dataset::Recording& plan, const std::vector<int>& beams) {
  std::vector<int> blocked;
  for (const auto& b : plan.beams)
    if (std::find(beams.begin(), beams.end(), b.id) == beams.end()) blocked.push_back(b.id);
  if (beams.empty())
    return "Block every beam (background frame: the board without laser dots, for the dot fit).";
  if (blocked.empty()) return "Unblock " + Beams(beams) + " (all beams).";
  return "Unblock " + Beams(beams) + " only; block " + Beams(blocked) +
         (beams.size() == 1 ? " (identification frame: tells which dot is which beam)." : ".");
}

int PoseCount(const dataset::Recording& plan) {
  int n = 0;
  for (const auto& f : plan.step1) n = std::max(n, f.pose + 1);
  return n;
}

std::string Fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

std::string Signed(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%+.0f", v);
  return buf;
}

std::string PoseWhere(const SlidingPlateState& p, int poses) {
  std::string s = "pose " + std::to_string(p.pose + 1) + " of " + std::to_string(poses);
  if (p.distance_mm > 0)
    s += " (about " + Fixed(p.distance_mm, 0) +
         " mm from the mirror position towards the source, tilted " + Signed(p.tilt_deg) + " deg)";
  return s;
}

std::vector<int> Sorted(std::vector<int> v) {
  std::sort(v.begin(), v.end());
  return v;
}

// What differs from `before` (nullopt: the first set-up, everything is listed).
std::vector<std::string> Changes(const std::optional<RigState>& before, const RigState& s,
                                 int poses) {
  std::vector<std::string> c;
  const bool all = !before.has_value();
  if (all || before->camera != s.camera)
    c.push_back(s.camera == "C1" ? "camera at the step-1 position C1 (sees both boards)"
                                 : "camera at the step-2 position C2 (sees the world board with "
                                   "the reflected dots)");
  if (all || before->msm_mounted != s.msm_mounted)
    c.push_back(s.msm_mounted ? "mount the MSM in the beam path" : "MSM not mounted");
  if (all || before->top_frame_mounted != s.top_frame_mounted)
    c.push_back(s.top_frame_mounted ? "mount the mirror's top frame"
                                    : "remove the mirror's top frame");
  if (all || !(before->sliding_plate == s.sliding_plate)) {
    if (!s.sliding_plate.mounted)
      c.push_back("remove the sliding plate");
    else
      c.push_back(std::string(all || !before->sliding_plate.mounted
                                  ? "mount the sliding plate at "
                                  : "move the sliding plate to ") +
                  PoseWhere(s.sliding_plate, poses));
  }
  std::vector<int> block, unblock;
  if (all) {
    unblock = s.beams_unblocked;
  } else {
    for (int b : before->beams_unblocked)
      if (!std::count(s.beams_unblocked.begin(), s.beams_unblocked.end(), b)) block.push_back(b);
    for (int b : s.beams_unblocked)
      if (!std::count(before->beams_unblocked.begin(), before->beams_unblocked.end(), b))
        unblock.push_back(b);
  }
  if (!block.empty()) c.push_back("block " + Beams(block));
  if (!unblock.empty()) c.push_back("unblock " + Beams(unblock));
  if (all && s.beams_unblocked.empty()) c.push_back("block every beam");
  return c;
}

RigState Step1State(const dataset::Step1Frame& f, const std::vector<PoseGeometry>& poses) {
  RigState s;
  s.camera = "C1";
  s.msm_mounted = false;
  s.top_frame_mounted = true;
  s.sliding_plate.mounted = true;
  s.sliding_plate.pose = f.pose;
  if (f.pose >= 0 && static_cast<size_t>(f.pose) < poses.size()) {
    s.sliding_plate.distance_mm = poses[f.pose].distance_mm;
    s.sliding_plate.tilt_deg = poses[f.pose].tilt_deg;
  }
  s.beams_unblocked = Sorted(f.beams);
  return s;
}

RigState Step2State(const dataset::Step2Frame& f) {
  RigState s;
  s.camera = "C2";
  s.msm_mounted = true;
  s.top_frame_mounted = true;
  s.beams_unblocked = Sorted(f.beams);
  return s;
}

// The drives the generators play for a step 2 frame (not physical: no set-up of its own).
Drive DriveOf(const dataset::Step2Frame& f) {
  return f.kind == dataset::Step2Kind::kNeutral    ? Drive::kOff
         : f.kind == dataset::Step2Kind::kFastOnly ? Drive::kFastOnly
                                                   : Drive::kScan;
}

// "Neutral frame: drives off ..." for one drive mode.
std::string DriveLine(Drive d) {
  switch (d) {
    case Drive::kOff:
      return "Neutral frame: drives off (fast and slow axis at rest).";
    case Drive::kFastOnly:
      return "Fast-only frame: fast axis driven, slow drive off.";
    case Drive::kScan:
      return "Scan frame: both drives on (full scan).";
  }
  return {};
}

std::vector<int> AllBeams(const dataset::Recording& plan) {
  std::vector<int> ids;
  for (const auto& b : plan.beams) ids.push_back(b.id);
  return Sorted(ids);
}

}  // namespace

const char* ToString(SetupStep step) {
  switch (step) {
    case SetupStep::kStep1:
      return "step1";
    case SetupStep::kHallBackground:
      return "hall_background";
    case SetupStep::kHallActual:
      return "hall_actual";
    case SetupStep::kStep2:
      return "step2";
  }
  return "?";
}

const char* ToString(Drive drive) {
  return drive == Drive::kOff ? "off" : drive == Drive::kFastOnly ? "fast_only" : "scan";
}

bool SlidingPlateState::operator==(const SlidingPlateState& o) const {
  if (mounted != o.mounted) return false;
  return !mounted || (pose == o.pose && distance_mm == o.distance_mm && tilt_deg == o.tilt_deg);
}

bool RigState::operator==(const RigState& o) const {
  return camera == o.camera && msm_mounted == o.msm_mounted &&
         top_frame_mounted == o.top_frame_mounted && sliding_plate == o.sliding_plate &&
         beams_unblocked == o.beams_unblocked;
}

bool Setup::operator==(const Setup& o) const {
  return block == o.block && of == o.of && step == o.step && frames == o.frames &&
         state == o.state && drive == o.drive && changes == o.changes && text == o.text;
}

std::string RenderSetupText(const Setup& s, const dataset::Recording& plan, bool background_first) {
  std::vector<std::string> items;
  const size_t n = s.frames.size();
  auto more = [&](const std::string& first) {
    std::string t = first;
    if (n > 1)
      t += " and " + std::to_string(n - 1) + " more at this set-up (" + s.frames.front() + " .. " +
           s.frames.back() + ")";
    else if (n == 1)
      t += " (" + s.frames.front() + ")";
    return t;
  };
  const int poses = PoseCount(plan);
  const RigState& st = s.state;
  switch (s.step) {
    case SetupStep::kHallBackground: {
      items.push_back(
          "Remove the mirror's top frame (magnet away from the sensor); leave the base with the "
          "Hall sensor and the drive coils in place: the coils are driven during the background "
          "recording.");
      items.push_back("Hall MCU connected (USB).");
      if (background_first) {
        items.push_back("Keep the MSM out of the beam path: step 1 (" +
                        std::to_string(plan.step1.size()) +
                        " frames) runs with the MSM not mounted; the background Hall recording "
                        "follows it without another prompt.");
        return Header(s.block, s.of, "Before step 1: background Hall recording set-up") +
               Numbered(items);
      }
      items.push_back(
          "Do not touch the rig while it records: the background Hall recording starts "
          "as soon as you confirm.");
      return Header(s.block, s.of, "Step 1 done: background Hall recording") + Numbered(items);
    }
    case SetupStep::kHallActual:
      items = {"Mount the mirror's top frame (MSM assembled, magnet over the Hall sensor).",
               "Put the MSM in the beam path, remove the sliding plate and move the camera to the "
               "step-2 position (it sees the world board with the reflected dots).",
               "The actual Hall recording runs during the whole of step 2 (" +
                   std::to_string(plan.step2.size()) + " frames)."};
      return Header(s.block, s.of, "Step 2 set-up: actual Hall recording") + Numbered(items);
    case SetupStep::kStep1: {
      const size_t first = s.frame_indices.empty() ? 0 : s.frame_indices.front();
      items.push_back("MSM not mounted: the beams go straight to the sliding plate.");
      const std::string where = PoseWhere(st.sliding_plate, poses);
      const bool same_pose = first > 0 && plan.step1[first - 1].pose == st.sliding_plate.pose;
      items.push_back(same_pose    ? "Leave the sliding plate at " + where + "."
                      : first == 0 ? "Mount the sliding plate at " + where + "."
                                   : "Move the sliding plate to " + where + ".");
      items.push_back("Both boards (sliding plate and world board) fully visible to the camera.");
      items.push_back(BeamsLine(plan, st.beams_unblocked));
      if (n > 1)
        items.push_back(std::to_string(n) +
                        " frames are taken at this set-up without another prompt (repeated "
                        "exposures: the solver averages them).");
      return Header(s.block, s.of,
                    more("Step 1, frame " + std::to_string(first + 1) + " of " +
                         std::to_string(plan.step1.size()))) +
             Numbered(items);
    }
    case SetupStep::kStep2: {
      const size_t first = s.frame_indices.empty() ? 0 : s.frame_indices.front();
      const dataset::Step2Frame& f = plan.step2.at(first);
      items.push_back("MSM mounted (top frame on), camera at the step-2 position.");
      // The drives are the generators' business (per-frame signals): said, not asked for.
      int kinds[3] = {0, 0, 0};
      for (size_t i : s.frame_indices) ++kinds[static_cast<int>(DriveOf(plan.step2.at(i)))];
      const int mixed = (kinds[0] > 0) + (kinds[1] > 0) + (kinds[2] > 0);
      if (mixed <= 1) {
        items.push_back(DriveLine(s.drive));
      } else {
        std::vector<std::string> parts;
        const char* what[3] = {"neutral (drives off)", "fast-only (fast drive only)",
                               "scan (both drives)"};
        for (int k = 0; k < 3; ++k)
          if (kinds[k] > 0) parts.push_back(std::to_string(kinds[k]) + " " + what[k]);
        std::string line = "Frames: ";
        for (size_t k = 0; k < parts.size(); ++k)
          line += (k == 0 ? "" : k + 1 == parts.size() ? " and " : ", ") + parts[k];
        items.push_back(line +
                        "; the generators switch the drives for each frame, nothing to change at "
                        "the rig.");
      }
      if (n == 1 && !f.triggers.empty()) {
        std::ostringstream t;
        t << "Laser pulses of trigger" << (f.triggers.size() == 1 ? " j = " : "s j = ")
          << JoinInts(f.triggers) << " (t = ";
        for (size_t i = 0; i < f.triggers.size(); ++i) {
          double t_s = -1;
          for (const auto& tr : plan.triggers)
            if (tr.j == f.triggers[i]) t_s = tr.t_s;
          t << (i ? ", " : "") << Fixed(t_s * 1e3, 3);
        }
        t << " ms in the pattern period).";
        items.push_back(t.str());
      } else if (n == 1) {
        items.push_back("Laser: continuous reference exposure (no trigger selection).");
      } else {
        items.push_back("Laser: the generators play the plan's trigger table; " +
                        std::to_string(n) +
                        " frames are taken at this set-up without another prompt.");
      }
      items.push_back(BeamsLine(plan, st.beams_unblocked));
      return Header(s.block, s.of,
                    more("Step 2, frame " + std::to_string(first + 1) + " of " +
                         std::to_string(plan.step2.size()) + ", " + dataset::ToString(f.kind))) +
             Numbered(items);
    }
  }
  return {};
}

SetupPlan PlanSetups(const dataset::Recording& plan, const std::vector<PoseGeometry>& poses,
                     bool background_first) {
  SetupPlan out;
  out.step1_setup.assign(plan.step1.size(), -1);
  out.step2_setup.assign(plan.step2.size(), -1);
  const std::vector<int> all = AllBeams(plan);
  auto add = [&](SetupStep step, const RigState& state, Drive drive) {
    Setup s;
    s.step = step;
    s.state = state;
    s.drive = drive;
    out.setups.push_back(s);
    return static_cast<int>(out.setups.size()) - 1;
  };
  auto background = [&](const RigState& before) {
    RigState s = before;
    s.msm_mounted = true;  // the base with the sensor and the coils in place
    s.top_frame_mounted = false;
    s.sliding_plate = {};
    out.background_setup =
        add(SetupStep::kHallBackground, s, Drive::kScan);  // coils driven as in step 2
  };
  RigState before1;
  before1.beams_unblocked = all;
  if (background_first) background(before1);
  for (size_t i = 0; i < plan.step1.size(); ++i) {
    const RigState s = Step1State(plan.step1[i], poses);
    if (out.setups.empty() || out.setups.back().step != SetupStep::kStep1 ||
        out.setups.back().state != s)
      add(SetupStep::kStep1, s, Drive::kOff);
    out.setups.back().frames.push_back(plan.step1[i].file);
    out.setups.back().frame_indices.push_back(i);
    out.step1_setup[i] = static_cast<int>(out.setups.size()) - 1;
  }
  const RigState last1 = out.setups.empty() ? before1 : out.setups.back().state;
  if (!background_first) background(last1);
  RigState actual;
  actual.camera = "C2";
  actual.msm_mounted = true;
  actual.top_frame_mounted = true;
  actual.beams_unblocked = out.setups.back().state.beams_unblocked;
  out.actual_setup = add(SetupStep::kHallActual, actual, Drive::kScan);
  for (size_t i = 0; i < plan.step2.size(); ++i) {
    const RigState s = Step2State(plan.step2[i]);
    if (out.setups.back().step != SetupStep::kStep2 || out.setups.back().state != s)
      add(SetupStep::kStep2, s, DriveOf(plan.step2[i]));
    out.setups.back().frames.push_back(plan.step2[i].file);
    out.setups.back().frame_indices.push_back(i);
    out.step2_setup[i] = static_cast<int>(out.setups.size()) - 1;
  }
  const int poses_n = PoseCount(plan);
  std::optional<RigState> prev;
  for (size_t k = 0; k < out.setups.size(); ++k) {
    Setup& s = out.setups[k];
    s.block = static_cast<int>(k) + 1;
    s.of = static_cast<int>(out.setups.size());
    s.changes = Changes(prev, s.state, poses_n);
    s.text = RenderSetupText(s, plan, background_first);
    prev = s.state;
  }
  return out;
}

std::string SetupToJson(const Setup& s) {
  json j;
  j["msmcal_setup"] = 1;
  j["kind"] = "setup";
  j["block"] = s.block;
  j["of"] = s.of;
  j["for"] = {{"step", ToString(s.step)}, {"frames", s.frames}};
  j["camera"] = s.state.camera;
  j["msm_mounted"] = s.state.msm_mounted;
  j["top_frame_mounted"] = s.state.top_frame_mounted;
  if (s.state.sliding_plate.mounted) {
    j["sliding_plate"] = {{"mounted", true},
                          {"pose", s.state.sliding_plate.pose},
                          {"distance_mm", s.state.sliding_plate.distance_mm},
                          {"tilt_deg", s.state.sliding_plate.tilt_deg}};
  } else {
    j["sliding_plate"] = {{"mounted", false}};
  }
  j["beams_unblocked"] = s.state.beams_unblocked;
  j["drive"] = ToString(s.drive);
  j["changes"] = s.changes;
  j["text"] = s.text;
  return j.dump();
}

Setup SetupFromJson(const std::string& text) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw std::runtime_error(std::string("setup JSON: ") + e.what());
  }
  auto need = [&](const json& at, const char* key, const std::string& field) -> const json& {
    if (!at.is_object() || !at.contains(key))
      throw std::runtime_error("setup JSON: " + field + ": missing");
    return at.at(key);
  };
  Setup s;
  try {
    if (need(j, "msmcal_setup", "msmcal_setup").get<int>() != 1)
      throw std::runtime_error("setup JSON: msmcal_setup: must be 1");
    if (need(j, "kind", "kind").get<std::string>() != "setup")
      throw std::runtime_error("setup JSON: kind: must be \"setup\"");
    s.block = need(j, "block", "block").get<int>();
    s.of = need(j, "of", "of").get<int>();
    const json& f = need(j, "for", "for");
    const std::string step = need(f, "step", "for.step").get<std::string>();
    bool known = false;
    for (SetupStep k : {SetupStep::kStep1, SetupStep::kHallBackground, SetupStep::kHallActual,
                        SetupStep::kStep2}) {
      if (step == ToString(k)) {
        s.step = k;
        known = true;
      }
    }
    if (!known) throw std::runtime_error("setup JSON: for.step = '" + step + "': unknown step");
    s.frames = need(f, "frames", "for.frames").get<std::vector<std::string>>();
    s.state.camera = need(j, "camera", "camera").get<std::string>();
    if (s.state.camera != "C1" && s.state.camera != "C2")
      throw std::runtime_error("setup JSON: camera = '" + s.state.camera + "': must be C1 or C2");
    s.state.msm_mounted = need(j, "msm_mounted", "msm_mounted").get<bool>();
    s.state.top_frame_mounted = need(j, "top_frame_mounted", "top_frame_mounted").get<bool>();
    const json& p = need(j, "sliding_plate", "sliding_plate");
    s.state.sliding_plate.mounted = need(p, "mounted", "sliding_plate.mounted").get<bool>();
    if (s.state.sliding_plate.mounted) {
      s.state.sliding_plate.pose = need(p, "pose", "sliding_plate.pose").get<int>();
      s.state.sliding_plate.distance_mm =
          need(p, "distance_mm", "sliding_plate.distance_mm").get<double>();
      s.state.sliding_plate.tilt_deg = need(p, "tilt_deg", "sliding_plate.tilt_deg").get<double>();
    }
    s.state.beams_unblocked = need(j, "beams_unblocked", "beams_unblocked").get<std::vector<int>>();
    const std::string drive = need(j, "drive", "drive").get<std::string>();
    if (drive == "off")
      s.drive = Drive::kOff;
    else if (drive == "fast_only")
      s.drive = Drive::kFastOnly;
    else if (drive == "scan")
      s.drive = Drive::kScan;
    else
      throw std::runtime_error("setup JSON: drive = '" + drive +
                               "': must be off, fast_only or scan");
    s.changes = need(j, "changes", "changes").get<std::vector<std::string>>();
    s.text = need(j, "text", "text").get<std::string>();
  } catch (const json::exception& e) {
    throw std::runtime_error(std::string("setup JSON: wrong type: ") + e.what());
  }
  return s;
}

std::string TruthRequestJson(const std::filesystem::path& dir) {
  json j;
  j["msmcal_setup"] = 1;
  j["kind"] = "truth_request";
  j["dir"] = std::filesystem::absolute(dir).lexically_normal().string();
  return j.dump();
}

}  // namespace msmcal::setup
