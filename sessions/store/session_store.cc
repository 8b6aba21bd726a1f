#include "sessions/store/session_store.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>

#include "common/text_io.h"
#include "sessions/interchange/interchange_io.h"

namespace msmcal::store {
namespace {

namespace fs = std::filesystem;

constexpr const char* kFormat = "msmcal-session/1";

// Schema version 1. Double-valued columns have no declared type (BLOB affinity) so that values
// are stored bit for bit: REAL affinity would store -0.0 as the integer 0.
constexpr const char* kSchema = R"sql(
CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE config(id INTEGER PRIMARY KEY CHECK (id = 1), yaml TEXT NOT NULL);
CREATE TABLE instruments(role TEXT PRIMARY KEY, identity TEXT NOT NULL);
CREATE TABLE triggers(seq INTEGER PRIMARY KEY, j INTEGER NOT NULL UNIQUE, t_s NOT NULL);
CREATE TABLE events(id INTEGER PRIMARY KEY, wall_time_ns INTEGER NOT NULL, generator_time_s,
                    kind TEXT NOT NULL, message TEXT NOT NULL);
CREATE TABLE frames(id INTEGER PRIMARY KEY,
                    step TEXT NOT NULL CHECK (step IN ('step1', 'step2')),
                    file TEXT NOT NULL UNIQUE, pose INTEGER, kind TEXT,
                    beams TEXT NOT NULL, triggers TEXT NOT NULL, accepted INTEGER NOT NULL,
                    quality TEXT NOT NULL, wall_time_ns INTEGER NOT NULL);
CREATE TABLE hall_readings(recording TEXT NOT NULL, seq INTEGER NOT NULL,
                           mcu_time_us INTEGER NOT NULL, bx_uT, by_uT, bz_uT,
                           PRIMARY KEY (recording, seq)) WITHOUT ROWID;
CREATE TABLE clock_edges(recording TEXT NOT NULL, seq INTEGER NOT NULL,
                         mcu_time_us INTEGER NOT NULL,
                         PRIMARY KEY (recording, seq)) WITHOUT ROWID;
CREATE TABLE results(name TEXT PRIMARY KEY, content BLOB NOT NULL, updated_ns INTEGER NOT NULL);
CREATE TABLE attachments(path TEXT PRIMARY KEY, content BLOB NOT NULL);
CREATE TABLE steps(name TEXT PRIMARY KEY,
                   state TEXT NOT NULL CHECK (state IN ('pending', 'running', 'done', 'failed')),
                   updated_ns INTEGER NOT NULL);
)sql";

[[noreturn]] void Fail(const fs::path& dir, const std::string& what) {
  throw StoreError("session " + dir.string() + ": " + what);
}

class Statement {
 public:
  Statement(sqlite3* db, const char* sql, const fs::path& dir) : db_(db), dir_(dir) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK) {
      Fail(dir_, std::string("SQL prepare failed: ") + sqlite3_errmsg(db) + " in: " + sql);
    }
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Statement& Bind(int i, int64_t v) {
    Check(sqlite3_bind_int64(stmt_, i, v));
    return *this;
  }
  Statement& Bind(int i, int v) { return Bind(i, static_cast<int64_t>(v)); }
  Statement& Bind(int i, double v) {
    Check(sqlite3_bind_double(stmt_, i, v));
    return *this;
  }
  Statement& Bind(int i, const std::string& v) {
    Check(sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
    return *this;
  }
  Statement& Bind(int i, const char* v) { return Bind(i, std::string(v)); }
  Statement& BindBlob(int i, const std::string& v) {
    Check(sqlite3_bind_blob64(stmt_, i, v.data(), v.size(), SQLITE_TRANSIENT));
    return *this;
  }
  Statement& BindNull(int i) {
    Check(sqlite3_bind_null(stmt_, i));
    return *this;
  }
  // True while a row is available.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    Fail(dir_, std::string("SQL step failed: ") + sqlite3_errmsg(db_));
  }
  void Run() {
    while (Step()) {
    }
  }
  void Reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  bool IsNull(int i) const { return sqlite3_column_type(stmt_, i) == SQLITE_NULL; }
  int64_t Int(int i) const { return sqlite3_column_int64(stmt_, i); }
  // NULL (SQLite's NaN) reads back as NaN.
  double Double(int i) const { return IsNull(i) ? NAN : sqlite3_column_double(stmt_, i); }
  std::string Text(int i) const {
    const void* p = sqlite3_column_blob(stmt_, i);
    const int n = sqlite3_column_bytes(stmt_, i);
    return p ? std::string(static_cast<const char*>(p), static_cast<size_t>(n)) : std::string();
  }

 private:
  void Check(int rc) {
    if (rc != SQLITE_OK) Fail(dir_, std::string("SQL bind failed: ") + sqlite3_errmsg(db_));
  }
  sqlite3* db_;
  const fs::path& dir_;
  sqlite3_stmt* stmt_ = nullptr;
};

void Exec(sqlite3* db, const std::string& sql, const fs::path& dir) {
  char* err = nullptr;
  if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
    const std::string msg = err ? err : sqlite3_errmsg(db);
    sqlite3_free(err);
    Fail(dir, "SQL failed: " + msg + " in: " + sql.substr(0, 80));
  }
}

// BEGIN IMMEDIATE ... COMMIT; rolls back if not committed.
class Transaction {
 public:
  Transaction(sqlite3* db, const fs::path& dir) : db_(db), dir_(dir) {
    Exec(db_, "BEGIN IMMEDIATE", dir_);
  }
  ~Transaction() {
    if (!done_) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }
  void Commit() {
    Exec(db_, "COMMIT", dir_);
    done_ = true;
  }

 private:
  sqlite3* db_;
  const fs::path& dir_;
  bool done_ = false;
};

std::string IntsToJson(const std::vector<int>& v) { return nlohmann::json(v).dump(); }

std::vector<int> IntsFromJson(const std::string& s, const fs::path& dir) {
  try {
    return nlohmann::json::parse(s).get<std::vector<int>>();
  } catch (const std::exception& e) {
    Fail(dir, "frames: bad integer list '" + s + "': " + e.what());
  }
}

void FsyncDir(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

// Relative, non-empty, inside the folder.
bool IsSafeRelativePath(const std::string& file) {
  const fs::path p(file);
  if (file.empty() || p.is_absolute()) return false;
  for (const auto& part : p) {
    if (part == "..") return false;
  }
  return true;
}

dataset::Step2Kind KindFromString(const std::string& s, const fs::path& dir) {
  if (s == "neutral") return dataset::Step2Kind::kNeutral;
  if (s == "fast_only") return dataset::Step2Kind::kFastOnly;
  if (s == "scan") return dataset::Step2Kind::kScan;
  Fail(dir, "frames: unknown kind '" + s + "'");
}

StepState StateFromString(const std::string& s) {
  if (s == "running") return StepState::kRunning;
  if (s == "done") return StepState::kDone;
  if (s == "failed") return StepState::kFailed;
  return StepState::kPending;
}

}  // namespace

int64_t SystemClock::NowNs() const {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

const char* ToString(StepState state) {
  switch (state) {
    case StepState::kPending:
      return "pending";
    case StepState::kRunning:
      return "running";
    case StepState::kDone:
      return "done";
    case StepState::kFailed:
      return "failed";
  }
  return "?";
}

struct SessionStore::Impl {
  fs::path dir;
  const Clock* clock = nullptr;
  sqlite3* db = nullptr;
  bool read_only = false;
  mutable std::mutex mutex;
  std::set<std::string> pending_files;  // frame files being written by AddFrame

  ~Impl() {
    if (db) sqlite3_close_v2(db);
  }

  void OpenDb(int flags) {
    const fs::path file = dir / kSessionDbName;
    if (sqlite3_open_v2(file.c_str(), &db, flags | SQLITE_OPEN_FULLMUTEX, nullptr) != SQLITE_OK) {
      const std::string msg = db ? sqlite3_errmsg(db) : "out of memory";
      Fail(dir, "cannot open " + file.string() + ": " + msg);
    }
    sqlite3_busy_timeout(db, 10000);
    sqlite3_extended_result_codes(db, 1);
  }

  void CheckWritable() const {
    if (read_only) Fail(dir, "opened read-only");
  }

  int64_t InsertFrame(const FrameRecord& f) {
    Statement s(db,
                "INSERT INTO frames(step, file, pose, kind, beams, triggers, accepted, quality, "
                "wall_time_ns) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                dir);
    s.Bind(1, f.step).Bind(2, f.file);
    if (f.step == "step1") {
      s.Bind(3, f.pose).BindNull(4);
    } else {
      s.BindNull(3).Bind(4, dataset::ToString(f.kind));
    }
    s.Bind(5, IntsToJson(f.beams))
        .Bind(6, IntsToJson(f.triggers))
        .Bind(7, f.accepted ? 1 : 0)
        .Bind(8, f.quality_json)
        .Bind(9, f.wall_time_ns != 0 ? f.wall_time_ns : clock->NowNs());
    s.Run();
    return sqlite3_last_insert_rowid(db);
  }

  void CheckFrame(const FrameRecord& f) const {
    if (f.step != "step1" && f.step != "step2") {
      Fail(dir, "frame " + f.file + ": step must be 'step1' or 'step2', got '" + f.step + "'");
    }
    if (!IsSafeRelativePath(f.file)) {
      Fail(dir, "frame file must be a relative path inside the session, got '" + f.file + "'");
    }
    try {
      if (!nlohmann::json::parse(f.quality_json).is_object()) throw std::runtime_error("");
    } catch (const std::exception&) {
      Fail(dir, "frame " + f.file + ": quality_json must be a JSON object, got '" + f.quality_json +
                    "'");
    }
  }

  bool FileReferenced(const std::string& file) const {
    Statement s(db, "SELECT 1 FROM frames WHERE file = ?", dir);
    s.Bind(1, file);
    return s.Step();
  }
};

SessionStore::SessionStore(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
SessionStore::~SessionStore() = default;

std::unique_ptr<SessionStore> SessionStore::Create(const fs::path& dir,
                                                   const SessionMetadata& metadata,
                                                   const Clock& clock) {
  std::error_code ec;
  if (fs::exists(dir / kSessionDbName, ec)) Fail(dir, "already holds a session");
  fs::create_directories(dir, ec);
  if (ec) Fail(dir, "cannot create folder: " + ec.message());
  auto impl = std::make_unique<Impl>();
  impl->dir = dir;
  impl->clock = &clock;
  impl->OpenDb(SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
  sqlite3* db = impl->db;
  {
    Statement s(db, "PRAGMA journal_mode=WAL", dir);
    if (!s.Step() || s.Text(0) != "wal") Fail(dir, "cannot switch the journal to WAL");
  }
  Exec(db, "PRAGMA synchronous=FULL", dir);

  dataset::Recording description = metadata.description;
  description.triggers.clear();
  description.step1.clear();
  description.step2.clear();
  description.format = dataset::kInterchangeFormat;
  const std::string problem = interchange::CheckRecording(description);
  if (!problem.empty()) Fail(dir, "invalid session description: " + problem);

  Transaction tx(db, dir);
  Exec(db, kSchema, dir);
  Exec(db, "PRAGMA user_version=" + std::to_string(kSchemaVersion), dir);
  Statement meta(db, "INSERT INTO meta(key, value) VALUES (?, ?)", dir);
  auto put = [&](const std::string& key, const std::string& value) {
    meta.Bind(1, key).Bind(2, value);
    meta.Run();
    meta.Reset();
  };
  put("format", kFormat);
  put("schema_version", std::to_string(kSchemaVersion));
  put("created_ns", std::to_string(clock.NowNs()));
  put("rig_id", metadata.rig_id);
  put("mirror_id", metadata.mirror_id);
  put("note", metadata.note);
  put("drive.fast.frequency_hz", interchange::FormatDouble(description.drive.fast.frequency_hz));
  put("drive.fast.amplitude_vpp", interchange::FormatDouble(description.drive.fast.amplitude_vpp));
  put("drive.slow.frequency_hz", interchange::FormatDouble(description.drive.slow.frequency_hz));
  put("drive.slow.amplitude_vpp", interchange::FormatDouble(description.drive.slow.amplitude_vpp));
  put("description_yaml", interchange::FormatSessionYaml(description));
  if (description.camera.Validate().empty()) {
    put("camera_yaml", interchange::FormatCameraYaml(description.camera));
  }
  Statement config(db, "INSERT INTO config(id, yaml) VALUES (1, ?)", dir);
  config.Bind(1, metadata.config_yaml).Run();
  tx.Commit();
  FsyncDir(dir);
  return std::unique_ptr<SessionStore>(new SessionStore(std::move(impl)));
}

std::unique_ptr<SessionStore> SessionStore::Open(const fs::path& dir, const Clock& clock,
                                                 bool read_only) {
  std::error_code ec;
  if (!fs::is_regular_file(dir / kSessionDbName, ec)) {
    Fail(dir, std::string("no ") + kSessionDbName + " (not a session folder)");
  }
  auto impl = std::make_unique<Impl>();
  impl->dir = dir;
  impl->clock = &clock;
  impl->read_only = read_only;
  impl->OpenDb(read_only ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE);
  {
    Statement s(impl->db, "PRAGMA user_version", dir);
    const int64_t version = s.Step() ? s.Int(0) : -1;
    if (version != kSchemaVersion) {
      Fail(dir, std::string(kSessionDbName) + " has schema version " + std::to_string(version) +
                    ", this msmcal reads version " + std::to_string(kSchemaVersion));
    }
  }
  if (!read_only) {
    Exec(impl->db, "PRAGMA synchronous=FULL", dir);
    // Temporaries of image writes that were interrupted (WriteFileAtomically names them
    // ".<name>.tmp-<pid>-<n>"); the database never references them.
    std::vector<fs::path> stale;
    for (auto it = fs::recursive_directory_iterator(dir, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (it->is_regular_file(ec) && name.size() > 1 && name[0] == '.' &&
          name.find(".tmp-") != std::string::npos) {
        stale.push_back(it->path());
      }
    }
    for (const auto& p : stale) fs::remove(p, ec);
  }
  return std::unique_ptr<SessionStore>(new SessionStore(std::move(impl)));
}

const fs::path& SessionStore::dir() const { return impl_->dir; }

void SessionStore::SetMeta(const std::string& key, const std::string& value) {
  std::lock_guard lock(impl_->mutex);
  impl_->CheckWritable();
  Statement s(impl_->db, "INSERT OR REPLACE INTO meta(key, value) VALUES (?, ?)", impl_->dir);
  s.Bind(1, key).Bind(2, value).Run();
}

std::optional<std::string> SessionStore::GetMeta(const std::string& key) const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "SELECT value FROM meta WHERE key = ?", impl_->dir);
  s.Bind(1, key);
  if (!s.Step()) return std::nullopt;
  return s.Text(0);
}

std::map<std::string, std::string> SessionStore::AllMeta() const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "SELECT key, value FROM meta", impl_->dir);
  std::map<std::string, std::string> out;
  while (s.Step()) out[s.Text(0)] = s.Text(1);
  return out;
}

dataset::Recording SessionStore::Description() const {
  dataset::Recording r;
  const auto text = GetMeta("description_yaml");
  if (!text) Fail(impl_->dir, "meta lacks description_yaml");
  try {
    interchange::ParseSessionYaml(*text, "meta.description_yaml", &r);
    if (const auto camera = GetMeta("camera_yaml")) {
      r.camera = interchange::ParseCameraYaml(*camera, "meta.camera_yaml");
    }
  } catch (const interchange::InterchangeError& e) {
    Fail(impl_->dir, e.what());
  }
  return r;
}

void SessionStore::SetConfigYaml(const std::string& yaml) {
  std::lock_guard lock(impl_->mutex);
  impl_->CheckWritable();
  Statement s(impl_->db, "INSERT OR REPLACE INTO config(id, yaml) VALUES (1, ?)", impl_->dir);
  s.Bind(1, yaml).Run();
}

std::string SessionStore::ConfigYaml() const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "SELECT yaml FROM config WHERE id = 1", impl_->dir);
  return s.Step() ? s.Text(0) : std::string();
}

void SessionStore::SetInstrument(const std::string& role, const std::string& identity) {
  std::lock_guard lock(impl_->mutex);
  impl_->CheckWritable();
  Statement s(impl_->db, "INSERT OR REPLACE INTO instruments(role, identity) VALUES (?, ?)",
              impl_->dir);
  s.Bind(1, role).Bind(2, identity).Run();
}

std::vector<std::pair<std::string, std::string>> SessionStore::Instruments() const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "SELECT role, identity FROM instruments ORDER BY role", impl_->dir);
  std::vector<std::pair<std::string, std::string>> out;
  while (s.Step()) out.emplace_back(s.Text(0), s.Text(1));
  return out;
}

void SessionStore::SetTriggers(const std::vector<dataset::Trigger>& triggers) {
  std::lock_guard lock(impl_->mutex);
  impl_->CheckWritable();
  std::set<int> seen;
  for (const auto& t : triggers) {
    if (!seen.insert(t.j).second) {
      Fail(impl_->dir, "triggers: index j=" + std::to_string(t.j) + " appears twice");
    }
  }
  Transaction tx(impl_->db, impl_->dir);
  Exec(impl_->db, "DELETE FROM triggers", impl_->dir);
  Statement s(impl_->db, "INSERT INTO triggers(seq, j, t_s) VALUES (?, ?, ?)", impl_->dir);
  for (size_t i = 0; i < triggers.size(); ++i) {
    s.Bind(1, static_cast<int64_t>(i)).Bind(2, triggers[i].j).Bind(3, triggers[i].t_s).Run();
    s.Reset();
  }
  tx.Commit();
}

std::vector<dataset::Trigger> SessionStore::Triggers() const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "SELECT j, t_s FROM triggers ORDER BY seq", impl_->dir);
  std::vector<dataset::Trigger> out;
  while (s.Step()) out.push_back({static_cast<int>(s.Int(0)), s.Double(1)});
  return out;
}

int64_t SessionStore::AddEvent(const std::string& kind, const std::string& message,
                               std::optional<double> generator_time_s) {
  std::lock_guard lock(impl_->mutex);
  impl_->CheckWritable();
  Statement s(impl_->db,
              "INSERT INTO events(wall_time_ns, generator_time_s, kind, message) "
              "VALUES (?, ?, ?, ?)",
              impl_->dir);
  s.Bind(1, impl_->clock->NowNs());
  if (generator_time_s) {
    s.Bind(2, *generator_time_s);
  } else {
    s.BindNull(2);
  }
  s.Bind(3, kind).Bind(4, message).Run();
  return sqlite3_last_insert_rowid(impl_->db);
}

std::vector<EventRecord> SessionStore::Events(int limit) const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db,
              "SELECT id, wall_time_ns, generator_time_s, kind, message FROM "
              "(SELECT * FROM events ORDER BY id DESC LIMIT ?) ORDER BY id",
              impl_->dir);
  s.Bind(1, static_cast<int64_t>(limit > 0 ? limit : -1));
  std::vector<EventRecord> out;
  while (s.Step()) {
    EventRecord e;
    e.id = s.Int(0);
    e.wall_time_ns = s.Int(1);
    if (!s.IsNull(2)) e.generator_time_s = s.Double(2);
    e.kind = s.Text(3);
    e.message = s.Text(4);
    out.push_back(std::move(e));
  }
  return out;
}

int64_t SessionStore::AddFrame(FrameRecord frame, const cv::Mat& image) {
  {
    std::lock_guard lock(impl_->mutex);
    impl_->CheckWritable();
    impl_->CheckFrame(frame);
    if (impl_->pending_files.count(frame.file) || impl_->FileReferenced(frame.file)) {
      Fail(impl_->dir, "frame file '" + frame.file + "' is already recorded");
    }
    impl_->pending_files.insert(frame.file);
  }
  // Encode and write outside the lock: other writers (Hall streams) keep going meanwhile.
  try {
    interchange::WriteImageAtomically(impl_->dir / frame.file, image);
  } catch (const std::exception& e) {
    std::lock_guard lock(impl_->mutex);
    impl_->pending_files.erase(frame.file);
    Fail(impl_->dir, e.what());
  }
  std::lock_guard lock(impl_->mutex);
  impl_->pending_files.erase(frame.file);
  return impl_->InsertFrame(frame);
}

int64_t SessionStore::AddFrameRecord(FrameRecord frame) {
  std::lock_guard lock(impl_->mutex);
  impl_->CheckWritable();
  impl_->CheckFrame(frame);
  std::error_code ec;
  if (!fs::is_regular_file(impl_->dir / frame.file, ec)) {
    Fail(impl_->dir, "frame file '" + frame.file + "' does not exist in the session folder");
  }
  if (impl_->pending_files.count(frame.file) || impl_->FileReferenced(frame.file)) {
    Fail(impl_->dir, "frame file '" + frame.file + "' is already recorded");
  }
  return impl_->InsertFrame(frame);
}

std::vector<FrameRecord> SessionStore::Frames() const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db,
              "SELECT id, step, file, pose, kind, beams, triggers, accepted, quality, "
              "wall_time_ns FROM frames ORDER BY id",
              impl_->dir);
  std::vector<FrameRecord> out;
  while (s.Step()) {
    FrameRecord f;
    f.id = s.Int(0);
    f.step = s.Text(1);
    f.file = s.Text(2);
    if (!s.IsNull(3)) f.pose = static_cast<int>(s.Int(3));
    if (!s.IsNull(4)) f.kind = KindFromString(s.Text(4), impl_->dir);
    f.beams = IntsFromJson(s.Text(5), impl_->dir);
    f.triggers = IntsFromJson(s.Text(6), impl_->dir);
    f.accepted = s.Int(7) != 0;
    f.quality_json = s.Text(8);
    f.wall_time_ns = s.Int(9);
    out.push_back(std::move(f));
  }
  return out;
}

void SessionStore::AppendHallReadings(const std::string& name,
                                      const std::vector<dataset::HallReading>& readings) {
  std::lock_guard lock(impl_->mutex);
  impl_->CheckWritable();
  if (readings.empty()) return;
  Transaction tx(impl_->db, impl_->dir);
  int64_t seq = 0;
  {
    Statement s(impl_->db, "SELECT MAX(seq) FROM hall_readings WHERE recording = ?", impl_->dir);
    s.Bind(1, name);
    if (s.Step() && !s.IsNull(0)) seq = s.Int(0) + 1;
  }
  Statement s(impl_->db,
              "INSERT INTO hall_readings(recording, seq, mcu_time_us, bx_uT, by_uT, bz_uT) "
              "VALUES (?, ?, ?, ?, ?, ?)",
              impl_->dir);
  for (const auto& r : readings) {
    s.Bind(1, name).Bind(2, seq++).Bind(3, r.mcu_time_us).Bind(4, r.bx_uT).Bind(5, r.by_uT);
    s.Bind(6, r.bz_uT).Run();
    s.Reset();
  }
  tx.Commit();
}

void SessionStore::AppendClockEdges(const std::string& name, const std::vector<double>& edges) {
  std::lock_guard lock(impl_->mutex);
  impl_->CheckWritable();
  if (edges.empty()) return;
  Transaction tx(impl_->db, impl_->dir);
  int64_t seq = 0;
  std::optional<double> last;
  {
    Statement s(impl_->db,
                "SELECT seq, mcu_time_us FROM clock_edges WHERE recording = ? "
                "ORDER BY seq DESC LIMIT 1",
                impl_->dir);
    s.Bind(1, name);
    if (s.Step()) {
      seq = s.Int(0) + 1;
      last = s.Double(1);
    }
  }
  Statement s(impl_->db, "INSERT INTO clock_edges(recording, seq, mcu_time_us) VALUES (?, ?, ?)",
              impl_->dir);
  for (double t : edges) {
    if (last && t <= *last) {
      Fail(impl_->dir, "clock edges of '" + name + "' must be strictly ascending: " +
                           common::ShortestDouble(t) + " after " + common::ShortestDouble(*last));
    }
    last = t;
    s.Bind(1, name).Bind(2, seq++).Bind(3, t).Run();
    s.Reset();
  }
  tx.Commit();
}

std::vector<dataset::HallReading> SessionStore::HallReadings(const std::string& name) const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db,
              "SELECT mcu_time_us, bx_uT, by_uT, bz_uT FROM hall_readings WHERE recording = ? "
              "ORDER BY seq",
              impl_->dir);
  s.Bind(1, name);
  std::vector<dataset::HallReading> out;
  while (s.Step()) out.push_back({s.Double(0), s.Double(1), s.Double(2), s.Double(3)});
  return out;
}

std::vector<double> SessionStore::ClockEdges(const std::string& name) const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "SELECT mcu_time_us FROM clock_edges WHERE recording = ? ORDER BY seq",
              impl_->dir);
  s.Bind(1, name);
  std::vector<double> out;
  while (s.Step()) out.push_back(s.Double(0));
  return out;
}

std::vector<std::string> SessionStore::HallRecordingNames() const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db,
              "SELECT DISTINCT recording FROM hall_readings UNION "
              "SELECT DISTINCT recording FROM clock_edges ORDER BY 1",
              impl_->dir);
  std::vector<std::string> out;
  while (s.Step()) out.push_back(s.Text(0));
  return out;
}

void SessionStore::PutResult(const std::string& name, const std::string& content) {
  std::lock_guard lock(impl_->mutex);
  impl_->CheckWritable();
  if (!IsSafeRelativePath(name)) Fail(impl_->dir, "result name '" + name + "' is not relative");
  Statement s(impl_->db,
              "INSERT OR REPLACE INTO results(name, content, updated_ns) VALUES (?, ?, ?)",
              impl_->dir);
  s.Bind(1, name).BindBlob(2, content).Bind(3, impl_->clock->NowNs()).Run();
}

std::optional<std::string> SessionStore::GetResult(const std::string& name) const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "SELECT content FROM results WHERE name = ?", impl_->dir);
  s.Bind(1, name);
  if (!s.Step()) return std::nullopt;
  return s.Text(0);
}

std::vector<std::string> SessionStore::ResultNames() const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "SELECT name FROM results ORDER BY name", impl_->dir);
  std::vector<std::string> out;
  while (s.Step()) out.push_back(s.Text(0));
  return out;
}

void SessionStore::PutAttachment(const std::string& path, const std::string& content) {
  std::lock_guard lock(impl_->mutex);
  impl_->CheckWritable();
  if (!IsSafeRelativePath(path)) Fail(impl_->dir, "attachment '" + path + "' is not relative");
  Statement s(impl_->db, "INSERT OR REPLACE INTO attachments(path, content) VALUES (?, ?)",
              impl_->dir);
  s.Bind(1, path).BindBlob(2, content).Run();
}

std::optional<std::string> SessionStore::GetAttachment(const std::string& path) const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "SELECT content FROM attachments WHERE path = ?", impl_->dir);
  s.Bind(1, path);
  if (!s.Step()) return std::nullopt;
  return s.Text(0);
}

std::vector<std::string> SessionStore::AttachmentPaths() const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "SELECT path FROM attachments ORDER BY path", impl_->dir);
  std::vector<std::string> out;
  while (s.Step()) out.push_back(s.Text(0));
  return out;
}

void SessionStore::SetStep(const std::string& name, StepState state) {
  std::lock_guard lock(impl_->mutex);
  impl_->CheckWritable();
  Statement s(impl_->db, "INSERT OR REPLACE INTO steps(name, state, updated_ns) VALUES (?, ?, ?)",
              impl_->dir);
  s.Bind(1, name).Bind(2, ToString(state)).Bind(3, impl_->clock->NowNs()).Run();
}

std::vector<std::pair<std::string, StepState>> SessionStore::Steps() const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "SELECT name, state FROM steps ORDER BY updated_ns, name", impl_->dir);
  std::vector<std::pair<std::string, StepState>> out;
  while (s.Step()) out.emplace_back(s.Text(0), StateFromString(s.Text(1)));
  return out;
}

SessionCounts SessionStore::Counts() const {
  std::lock_guard lock(impl_->mutex);
  SessionCounts c;
  auto count = [&](const char* sql) {
    Statement s(impl_->db, sql, impl_->dir);
    return s.Step() ? s.Int(0) : int64_t{0};
  };
  c.frames = count("SELECT COUNT(*) FROM frames");
  c.events = count("SELECT COUNT(*) FROM events");
  c.triggers = count("SELECT COUNT(*) FROM triggers");
  c.results = count("SELECT COUNT(*) FROM results");
  {
    Statement s(impl_->db, "SELECT recording, COUNT(*) FROM hall_readings GROUP BY recording",
                impl_->dir);
    while (s.Step()) c.hall_readings[s.Text(0)] = s.Int(1);
  }
  {
    Statement s(impl_->db, "SELECT recording, COUNT(*) FROM clock_edges GROUP BY recording",
                impl_->dir);
    while (s.Step()) c.clock_edges[s.Text(0)] = s.Int(1);
  }
  return c;
}

std::string SessionStore::IntegrityCheck() const {
  std::lock_guard lock(impl_->mutex);
  Statement s(impl_->db, "PRAGMA integrity_check", impl_->dir);
  std::string out;
  while (s.Step()) out += (out.empty() ? "" : "\n") + s.Text(0);
  return out;
}

}  // namespace msmcal::store
