#pragma once
// The durable session store (issue 9): one session = one folder holding `session.db` (SQLite,
// WAL journal) and the frame images beside it (`step1/*.png`, `step2/*.png`, written
// atomically: temporary, fsync, rename). Every call that records data commits before it
// returns, so data reaches disk as it is captured; a process killed at any point (SIGKILL
// included) leaves a database that reopens consistent, holding every call that returned.
//
// Durability: `PRAGMA synchronous=FULL` with WAL: each commit fsyncs the WAL. NORMAL would be
// crash-safe too (never corrupt) but may lose the last commits on power loss, and the issue asks
// that data reach disk as it is captured. Hall readings are inserted in batches (one
// transaction per AppendHallReadings call) so a 1 kHz stream costs a few commits per second.
//
// Numbers: doubles are stored bit for bit (-0.0 and subnormals included; columns have no
// declared type because REAL affinity would store -0.0 as the integer 0). SQLite cannot store
// NaN: a NaN reads back as a quiet NaN.
//
// Thread safety: all methods may be called from several threads (one connection, serialised by
// an internal mutex). Errors: StoreError naming the session folder and what failed.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "processing/dataset/recording.h"

namespace cv {
class Mat;
}

namespace msmcal::store {

class StoreError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Wall-clock source, injected so that tests are deterministic.
class Clock {
 public:
  virtual ~Clock() = default;
  // Nanoseconds since the Unix epoch (UTC).
  virtual int64_t NowNs() const = 0;
};

// std::chrono::system_clock.
class SystemClock : public Clock {
 public:
  int64_t NowNs() const override;
};

// A clock that returns what it is set to, advancing by `step_ns` after each reading.
// Thread-safe.
class FakeClock : public Clock {
 public:
  explicit FakeClock(int64_t start_ns = 0, int64_t step_ns = 0)
      : now_ns_(start_ns), step_ns_(step_ns) {}
  int64_t NowNs() const override { return now_ns_.fetch_add(step_ns_); }
  void Set(int64_t now_ns) { now_ns_.store(now_ns); }

 private:
  mutable std::atomic<int64_t> now_ns_;
  int64_t step_ns_;
};

inline constexpr const char* kSessionDbName = "session.db";
inline constexpr int kSchemaVersion = 1;

// What a session is about; the figures a lab filters by.
struct SessionMetadata {
  std::string rig_id;
  std::string mirror_id;
  std::string note;
  // Session layout: camera, boards, beams, drive and clock of `description` are stored; its
  // frames, triggers, Hall and MARG recordings are ignored (they go to their own tables).
  dataset::Recording description;
  std::string config_yaml;  // the run configuration, verbatim (may be empty)
};

enum class StepState { kPending, kRunning, kDone, kFailed };
const char* ToString(StepState state);  // "pending" | "running" | "done" | "failed"

struct EventRecord {
  int64_t id = 0;
  int64_t wall_time_ns = 0;
  std::optional<double> generator_time_s;
  std::string kind;  // e.g. "info", "warning", "error", "step"
  std::string message;
};

// One camera frame. `step` is "step1" or "step2"; step1 frames carry `pose`, step2 frames
// `kind` and `triggers`. `file` is relative to the session folder.
struct FrameRecord {
  int64_t id = 0;  // assigned by the store
  std::string step;
  std::string file;
  int pose = 0;
  dataset::Step2Kind kind = dataset::Step2Kind::kScan;
  std::vector<int> beams;
  std::vector<int> triggers;
  bool accepted = true;
  std::string quality_json = "{}";  // quality figures (sharpness, dot count, ...), JSON object
  int64_t wall_time_ns = 0;         // 0: the store's clock at insertion
};

// Counts for `sessions show` and the catalogue.
struct SessionCounts {
  int64_t frames = 0;
  int64_t events = 0;
  int64_t triggers = 0;
  std::map<std::string, int64_t> hall_readings;  // per recording name
  std::map<std::string, int64_t> clock_edges;
  int64_t results = 0;
};

class SessionStore {
 public:
  // Creates `dir` (which must not already hold a session) and a new database with `metadata`.
  static std::unique_ptr<SessionStore> Create(const std::filesystem::path& dir,
                                              const SessionMetadata& metadata, const Clock& clock);
  // Opens an existing session. Removes temporaries left by an interrupted image write.
  // `read_only`: no writes, no clean-up (for catalogues and export).
  static std::unique_ptr<SessionStore> Open(const std::filesystem::path& dir, const Clock& clock,
                                            bool read_only = false);
  ~SessionStore();
  SessionStore(const SessionStore&) = delete;
  SessionStore& operator=(const SessionStore&) = delete;

  const std::filesystem::path& dir() const;

  // meta table (key/value). Keys written by Create: format, schema_version, created_ns, rig_id,
  // mirror_id, note, drive.fast.frequency_hz, drive.fast.amplitude_vpp, drive.slow.frequency_hz,
  // drive.slow.amplitude_vpp, description_yaml, camera_yaml.
  void SetMeta(const std::string& key, const std::string& value);
  std::optional<std::string> GetMeta(const std::string& key) const;
  std::map<std::string, std::string> AllMeta() const;
  // Camera, boards, beams, drive, clock of the session (frames etc. empty).
  dataset::Recording Description() const;

  void SetConfigYaml(const std::string& yaml);
  std::string ConfigYaml() const;

  void SetInstrument(const std::string& role, const std::string& identity);
  std::vector<std::pair<std::string, std::string>> Instruments() const;

  // Replaces the trigger table.
  void SetTriggers(const std::vector<dataset::Trigger>& triggers);
  std::vector<dataset::Trigger> Triggers() const;

  // Appends an event stamped with the store's clock; returns its id.
  int64_t AddEvent(const std::string& kind, const std::string& message,
                   std::optional<double> generator_time_s = std::nullopt);
  // The last `limit` events (all if limit <= 0), oldest first.
  std::vector<EventRecord> Events(int limit = 0) const;

  // Writes `image` to dir()/frame.file atomically (PNG), then commits the frame's row; returns
  // its id. A kill between the two leaves an unreferenced image, never a referenced partial one.
  int64_t AddFrame(FrameRecord frame, const cv::Mat& image);
  // Commits a frame whose image file already exists under dir() (import).
  int64_t AddFrameRecord(FrameRecord frame);
  std::vector<FrameRecord> Frames() const;

  // Appends readings of Hall recording `name` ("actual", "background", ...) in one transaction.
  void AppendHallReadings(const std::string& name,
                          const std::vector<dataset::HallReading>& readings);
  void AppendClockEdges(const std::string& name, const std::vector<double>& edges_us);
  std::vector<dataset::HallReading> HallReadings(const std::string& name) const;
  std::vector<double> ClockEdges(const std::string& name) const;
  std::vector<std::string> HallRecordingNames() const;

  // results/ files verbatim, by name relative to results/ ("mirror_planes.csv").
  void PutResult(const std::string& name, const std::string& content);
  std::optional<std::string> GetResult(const std::string& name) const;
  std::vector<std::string> ResultNames() const;

  // Other files of an imported folder kept verbatim (marg/*, truth/*), by relative path.
  void PutAttachment(const std::string& path, const std::string& content);
  std::optional<std::string> GetAttachment(const std::string& path) const;
  std::vector<std::string> AttachmentPaths() const;

  void SetStep(const std::string& name, StepState state);
  std::vector<std::pair<std::string, StepState>> Steps() const;

  SessionCounts Counts() const;
  // SQLite's PRAGMA integrity_check: "ok" when consistent.
  std::string IntegrityCheck() const;

 private:
  struct Impl;
  explicit SessionStore(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace msmcal::store
