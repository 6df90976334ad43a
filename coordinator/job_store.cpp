#include "coordinator/job_store.h"

#include <sqlite3.h>

#include <chrono>
#include <stdexcept>

#include "common/farm/proto_convert.h"
#include "coordinator/storage_full.h"

namespace lightfarm {

namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// A full disk is StorageFull (the coordinator waits for space); anything else is an error.
[[noreturn]] void ThrowSqlite(sqlite3* db, int rc, const std::string& what) {
  const std::string message = what + sqlite3_errmsg(db);
  if ((rc & 0xff) == SQLITE_FULL || (rc & 0xff) == SQLITE_IOERR) {
    // SQLITE_IOERR_WRITE and friends carry the system's errno: ENOSPC is a full disk too.
    if ((rc & 0xff) == SQLITE_FULL || IsNoSpaceErrno(sqlite3_system_errno(db))) throw StorageFull(message);
  }
  throw std::runtime_error(message);
}

// A prepared statement with positional binding; throws on any SQLite error.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) : db_(db) {
    if (sqlite3_prepare_v2(db, sql, -1, &st_, nullptr) != SQLITE_OK)
      throw std::runtime_error(std::string("sqlite prepare: ") + sqlite3_errmsg(db));
  }
  // A statement prepared once and kept (the hot path's): reset for reuse instead of finalized.
  Stmt(sqlite3* db, sqlite3_stmt* prepared) : db_(db), st_(prepared), cached_(true) {}
  ~Stmt() {
    if (cached_) {
      sqlite3_reset(st_);
      sqlite3_clear_bindings(st_);
    } else {
      sqlite3_finalize(st_);
    }
  }
  Stmt& Bind(int64_t v) { Check(sqlite3_bind_int64(st_, ++n_, v)); return *this; }
  Stmt& Bind(int v) { return Bind(int64_t(v)); }
  Stmt& Bind(double v) { Check(sqlite3_bind_double(st_, ++n_, v)); return *this; }
  Stmt& Bind(const std::string& v) {  // text (names, hashes, messages)
    Check(sqlite3_bind_text(st_, ++n_, v.data(), int(v.size()), SQLITE_TRANSIENT));
    return *this;
  }
  Stmt& BindBlob(const std::string& v) {  // binary (serialized protobuf)
    Check(sqlite3_bind_blob(st_, ++n_, v.data(), int(v.size()), SQLITE_TRANSIENT));
    return *this;
  }
  bool Step() {
    int rc = sqlite3_step(st_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    ThrowSqlite(db_, rc, "sqlite step: ");
  }
  int64_t Int(int col) { return sqlite3_column_int64(st_, col); }
  double Real(int col) { return sqlite3_column_double(st_, col); }
  std::string Str(int col) {
    const void* p = sqlite3_column_blob(st_, col);
    int n = sqlite3_column_bytes(st_, col);
    return p ? std::string(static_cast<const char*>(p), size_t(n)) : std::string();
  }

 private:
  void Check(int rc) {
    if (rc != SQLITE_OK) throw std::runtime_error(std::string("sqlite bind: ") + sqlite3_errmsg(db_));
  }
  sqlite3* db_;
  sqlite3_stmt* st_ = nullptr;
  bool cached_ = false;
  int n_ = 0;
};

}  // namespace

JobStore::JobStore(const std::string& path) {
  if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE |
                      SQLITE_OPEN_FULLMUTEX, nullptr) != SQLITE_OK) {
    const std::string error = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    throw std::runtime_error("cannot open state database " + path + ": " + error);
  }
  try {
    Initialize(path);
  } catch (const StorageFull&) {
    sqlite3_close(db_);
    throw;
  } catch (const std::exception& e) {
    sqlite3_close(db_);  // a refused database is closed: the caller may open another
    const std::string what = e.what();
    if (what.find(path) != std::string::npos) throw;
    throw std::runtime_error("state database " + path + " cannot be used (" + what + "); restore it from a backup");
  }
}

void JobStore::Initialize(const std::string& path) {
  sqlite3_busy_timeout(db_, 5000);
  sqlite3_extended_result_codes(db_, 1);
  // A damaged database is refused before anything is read from or written to it.
  {
    Stmt check(db_, "PRAGMA quick_check");
    std::string problems;
    while (check.Step()) {
      const std::string row = check.Str(0);
      if (row != "ok" && problems.size() < 2000) problems += (problems.empty() ? "" : "; ") + row;
    }
    if (!problems.empty())
      throw std::runtime_error("state database " + path + " is damaged (SQLite quick_check: " + problems +
                               "); restore it from a backup");
  }
  // WAL + NORMAL: a killed process loses nothing committed; only an OS crash may lose the
  // last transactions, which re-running those tasks repairs.
  Exec("PRAGMA journal_mode=WAL");
  Exec("PRAGMA synchronous=NORMAL");
  Exec(R"(CREATE TABLE IF NOT EXISTS jobs(
          id INTEGER PRIMARY KEY AUTOINCREMENT, name TEXT, priority INTEGER, state INTEGER,
          manifest BLOB, settings BLOB, stage INTEGER DEFAULT 0, error TEXT DEFAULT '',
          created REAL, finished REAL, result_sha TEXT DEFAULT '', stats_json TEXT DEFAULT '',
          pass INTEGER DEFAULT 0, accum_sha TEXT DEFAULT ''))");
  // State directories from before progressive jobs: the pass columns are added.
  {
    bool has_pass = false;
    Stmt columns(db_, "PRAGMA table_info(jobs)");
    while (columns.Step()) has_pass |= columns.Str(1) == "pass";
    if (!has_pass) {
      Exec("ALTER TABLE jobs ADD COLUMN pass INTEGER DEFAULT 0");
      Exec("ALTER TABLE jobs ADD COLUMN accum_sha TEXT DEFAULT ''");
    }
  }
  Exec(R"(CREATE TABLE IF NOT EXISTS stages(
          job_id INTEGER, stage INTEGER, artifact_sha TEXT, PRIMARY KEY(job_id, stage)))");
  Exec(R"(CREATE TABLE IF NOT EXISTS tasks(
          job_id INTEGER, stage INTEGER, task_id INTEGER, state INTEGER DEFAULT 0,
          attempts INTEGER DEFAULT 0, failures INTEGER DEFAULT 0, result_sha TEXT DEFAULT '',
          last_error TEXT DEFAULT '', PRIMARY KEY(job_id, stage, task_id)))");
  Exec(R"(CREATE TABLE IF NOT EXISTS attempts(
          id INTEGER PRIMARY KEY AUTOINCREMENT, job_id INTEGER, stage INTEGER, task_id INTEGER,
          worker_id TEXT, started REAL, ended REAL, outcome TEXT DEFAULT ''))");
  Exec(R"(CREATE TABLE IF NOT EXISTS workers(
          id TEXT PRIMARY KEY, name TEXT, version TEXT, registered REAL, threads INTEGER DEFAULT 0))");
  {
    bool has_threads = false;  // state directories from before the dashboard
    Stmt columns(db_, "PRAGMA table_info(workers)");
    while (columns.Step()) has_threads |= columns.Str(1) == "threads";
    if (!has_threads) Exec("ALTER TABLE workers ADD COLUMN threads INTEGER DEFAULT 0");
  }
  {
    bool has_blocklisted = false;  // state directories from before result verification
    Stmt columns(db_, "PRAGMA table_info(workers)");
    while (columns.Step()) has_blocklisted |= columns.Str(1) == "blocklisted";
    if (!has_blocklisted) Exec("ALTER TABLE workers ADD COLUMN blocklisted TEXT DEFAULT ''");
  }
}

JobStore::~JobStore() {
  for (auto& [sql, st] : prepared_) sqlite3_finalize(st);
  sqlite3_close(db_);
}

sqlite3_stmt* JobStore::Prepared(const char* sql) {
  auto it = prepared_.find(sql);
  if (it != prepared_.end()) return it->second;
  sqlite3_stmt* st = nullptr;
  if (sqlite3_prepare_v3(db_, sql, -1, SQLITE_PREPARE_PERSISTENT, &st, nullptr) != SQLITE_OK)
    throw std::runtime_error(std::string("sqlite prepare: ") + sqlite3_errmsg(db_));
  prepared_.emplace(sql, st);
  return st;
}

// The statements of a task's life, each prepared once.
static const char* const kInsertAttempt =
    "INSERT INTO attempts(job_id, stage, task_id, worker_id, started) VALUES(?, ?, ?, ?, ?)";
static const char* const kUpdateTask =
    "UPDATE tasks SET state = ?, attempts = ?, failures = ?, result_sha = ?, last_error = ? "
    "WHERE job_id = ? AND stage = ? AND task_id = ?";
static const char* const kEndAttempt = "UPDATE attempts SET ended = ?, outcome = ? WHERE id = ?";

void JobStore::WriteTask(int64_t job, const TaskRecord& t) {
  Stmt(db_, Prepared(kUpdateTask))
      .Bind(t.state).Bind(t.attempts).Bind(t.failures).Bind(t.result_sha).Bind(t.last_error)
      .Bind(job).Bind(t.stage).Bind(t.task_id).Step();
}

void JobStore::WriteAttemptEnd(int64_t attempt, const std::string& outcome) {
  Stmt(db_, Prepared(kEndAttempt)).Bind(Now()).Bind(outcome).Bind(attempt).Step();
}

int64_t JobStore::RecordLease(int64_t job, const TaskRecord& t, const std::string& worker) {
  std::lock_guard lock(mu_);
  Exec("BEGIN");
  try {
    Stmt(db_, Prepared(kInsertAttempt)).Bind(job).Bind(t.stage).Bind(t.task_id).Bind(worker).Bind(Now()).Step();
    const int64_t attempt = sqlite3_last_insert_rowid(db_);
    WriteTask(job, t);
    Exec("COMMIT");
    return attempt;
  } catch (...) {
    Exec("ROLLBACK");
    throw;
  }
}

void JobStore::RecordCompletion(int64_t job, const TaskRecord& t, int64_t attempt) {
  std::lock_guard lock(mu_);
  Exec("BEGIN");
  try {
    WriteTask(job, t);
    if (attempt) WriteAttemptEnd(attempt, "done");
    Exec("COMMIT");
  } catch (...) {
    Exec("ROLLBACK");
    throw;
  }
}

void JobStore::Exec(const char* sql) {
  char* err = nullptr;
  const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, &err);
  if (rc != SQLITE_OK) {
    sqlite3_free(err);
    ThrowSqlite(db_, rc, "sqlite: ");
  }
}

int64_t JobStore::InsertJob(const JobRecord& j) {
  std::lock_guard lock(mu_);
  Stmt s(db_, "INSERT INTO jobs(name, priority, state, manifest, settings, created) "
              "VALUES(?, ?, ?, ?, ?, ?)");
  s.Bind(j.name).Bind(j.priority).Bind(int(j.state)).BindBlob(EncodeManifest(j.manifest)).BindBlob(EncodeSettings(j.settings)).Bind(Now()).Step();
  return sqlite3_last_insert_rowid(db_);
}

void JobStore::SetJobState(int64_t id, JobState state, const std::string& error) {
  std::lock_guard lock(mu_);
  // A job that ends records when: the retention policy counts from it.
  Stmt(db_, "UPDATE jobs SET state = ?, error = ?, finished = CASE WHEN ? THEN ? ELSE finished END WHERE id = ?")
      .Bind(int(state)).Bind(error).Bind(int(IsTerminal(state))).Bind(Now()).Bind(id).Step();
}

void JobStore::SetJobStage(int64_t id, int stage) {
  std::lock_guard lock(mu_);
  Stmt(db_, "UPDATE jobs SET stage = ? WHERE id = ?").Bind(stage).Bind(id).Step();
}

void JobStore::FinishJob(int64_t id, JobState state, const std::string& result_sha,
                         const std::string& stats_json) {
  std::lock_guard lock(mu_);
  Stmt(db_, "UPDATE jobs SET state = ?, result_sha = ?, stats_json = ?, finished = ? WHERE id = ?")
      .Bind(int(state)).Bind(result_sha).Bind(stats_json).Bind(Now()).Bind(id).Step();
}

void JobStore::FinishPass(int64_t id, int next_pass, const std::string& accum_sha,
                          const std::string& result_sha, const std::string& stats_json) {
  std::lock_guard lock(mu_);
  Exec("BEGIN");
  try {
    Stmt(db_, "UPDATE jobs SET pass = ?, stage = 0, accum_sha = ?, result_sha = ?, stats_json = ? WHERE id = ?")
        .Bind(next_pass).Bind(accum_sha).Bind(result_sha).Bind(stats_json).Bind(id).Step();
    Stmt(db_, "DELETE FROM tasks WHERE job_id = ?").Bind(id).Step();
    Stmt(db_, "DELETE FROM stages WHERE job_id = ?").Bind(id).Step();
    Exec("COMMIT");
  } catch (...) {
    Exec("ROLLBACK");
    throw;
  }
}

void JobStore::SetArtifact(int64_t id, int stage, const std::string& sha) {
  std::lock_guard lock(mu_);
  Stmt(db_, "INSERT OR REPLACE INTO stages(job_id, stage, artifact_sha) VALUES(?, ?, ?)")
      .Bind(id).Bind(stage).Bind(sha).Step();
}

std::map<int, std::string> JobStore::Artifacts(int64_t id) {
  std::lock_guard lock(mu_);
  Stmt s(db_, "SELECT stage, artifact_sha FROM stages WHERE job_id = ?");
  s.Bind(id);
  std::map<int, std::string> out;
  while (s.Step()) out[int(s.Int(0))] = s.Str(1);
  return out;
}

void JobStore::InsertTasks(int64_t id, int stage, int count) {
  std::lock_guard lock(mu_);
  Exec("BEGIN");
  try {
    for (int t = 0; t < count; ++t)
      Stmt(db_, "INSERT OR IGNORE INTO tasks(job_id, stage, task_id) VALUES(?, ?, ?)")
          .Bind(id).Bind(stage).Bind(t).Step();
    Exec("COMMIT");
  } catch (...) {
    Exec("ROLLBACK");
    throw;
  }
}

void JobStore::UpdateTask(int64_t id, const TaskRecord& t) {
  std::lock_guard lock(mu_);
  WriteTask(id, t);
}

static std::vector<TaskRecord> ReadTasks(Stmt& s) {
  std::vector<TaskRecord> out;
  while (s.Step()) {
    TaskRecord t;
    t.stage = int(s.Int(0));
    t.task_id = int(s.Int(1));
    t.state = int(s.Int(2));
    t.attempts = int(s.Int(3));
    t.failures = int(s.Int(4));
    t.result_sha = s.Str(5);
    t.last_error = s.Str(6);
    out.push_back(std::move(t));
  }
  return out;
}

std::vector<TaskRecord> JobStore::LoadTasks(int64_t id, int stage) {
  std::lock_guard lock(mu_);
  Stmt s(db_, "SELECT stage, task_id, state, attempts, failures, result_sha, last_error FROM tasks "
              "WHERE job_id = ? AND stage = ? ORDER BY task_id");
  s.Bind(id).Bind(stage);
  return ReadTasks(s);
}

std::vector<TaskRecord> JobStore::LoadAllTasks(int64_t id) {
  std::lock_guard lock(mu_);
  Stmt s(db_, "SELECT stage, task_id, state, attempts, failures, result_sha, last_error FROM tasks "
              "WHERE job_id = ? ORDER BY stage, task_id");
  s.Bind(id);
  return ReadTasks(s);
}

void JobStore::EndAttempt(int64_t attempt, const std::string& outcome) {
  std::lock_guard lock(mu_);
  WriteAttemptEnd(attempt, outcome);
}

std::vector<JobRecord> JobStore::LoadJobs() {
  std::lock_guard lock(mu_);
  Stmt s(db_, "SELECT id, name, priority, state, manifest, settings, stage, error, created, "
              "result_sha, stats_json, pass, accum_sha, finished FROM jobs ORDER BY id");
  std::vector<JobRecord> out;
  while (s.Step()) {
    JobRecord j;
    j.id = s.Int(0);
    j.name = s.Str(1);
    j.priority = int(s.Int(2));
    j.state = JobState(int(s.Int(3)));
    j.manifest = DecodeManifest(s.Str(4));
    j.settings = DecodeSettings(s.Str(5));
    j.stage = int(s.Int(6));
    j.error = s.Str(7);
    j.created = s.Real(8);
    j.result_sha = s.Str(9);
    j.stats_json = s.Str(10);
    j.pass = int(s.Int(11));
    j.accum_sha = s.Str(12);
    j.finished = s.Real(13);
    out.push_back(std::move(j));
  }
  return out;
}

void JobStore::UpsertWorker(const WorkerRecord& w) {
  std::lock_guard lock(mu_);
  Stmt(db_, "INSERT OR REPLACE INTO workers(id, name, version, registered, threads) VALUES(?, ?, ?, ?, ?)")
      .Bind(w.id).Bind(w.name).Bind(w.version).Bind(Now()).Bind(w.threads).Step();
}

std::vector<JobStore::WorkerRecord> JobStore::LoadWorkers() {
  std::lock_guard lock(mu_);
  Stmt s(db_, "SELECT id, name, version, threads, blocklisted FROM workers");
  std::vector<WorkerRecord> out;
  while (s.Step()) out.push_back(WorkerRecord{s.Str(0), s.Str(1), s.Str(2), int(s.Int(3)), s.Str(4)});
  return out;
}

void JobStore::SetWorkerBlocklisted(const std::string& id, const std::string& reason) {
  std::lock_guard lock(mu_);
  Stmt(db_, "UPDATE workers SET blocklisted = ? WHERE id = ?").Bind(reason).Bind(id).Step();
}

std::vector<std::pair<int, int>> JobStore::TasksDoneBy(int64_t job, const std::string& worker) {
  std::lock_guard lock(mu_);
  Stmt s(db_, "SELECT DISTINCT stage, task_id FROM attempts WHERE job_id = ? AND worker_id = ? AND outcome = 'done'");
  s.Bind(job).Bind(worker);
  std::vector<std::pair<int, int>> out;
  while (s.Step()) out.emplace_back(int(s.Int(0)), int(s.Int(1)));
  return out;
}

void JobStore::DeleteJob(int64_t id) {
  std::lock_guard lock(mu_);
  Exec("BEGIN");
  try {
    for (const char* sql : {"DELETE FROM attempts WHERE job_id = ?", "DELETE FROM tasks WHERE job_id = ?",
                            "DELETE FROM stages WHERE job_id = ?", "DELETE FROM jobs WHERE id = ?"})
      Stmt(db_, sql).Bind(id).Step();
    Exec("COMMIT");
  } catch (...) {
    Exec("ROLLBACK");
    throw;
  }
}

void JobStore::DeleteOrphans() {
  std::lock_guard lock(mu_);
  for (const char* sql : {"DELETE FROM attempts WHERE job_id NOT IN (SELECT id FROM jobs)",
                          "DELETE FROM tasks WHERE job_id NOT IN (SELECT id FROM jobs)",
                          "DELETE FROM stages WHERE job_id NOT IN (SELECT id FROM jobs)"})
    Exec(sql);
}

std::vector<std::string> JobStore::ReferencedBlobs() {
  std::lock_guard lock(mu_);
  std::vector<std::string> out;
  Stmt s(db_,
         "SELECT result_sha FROM jobs UNION SELECT accum_sha FROM jobs UNION SELECT result_sha FROM tasks "
         "UNION SELECT artifact_sha FROM stages");
  while (s.Step()) {
    std::string sha = s.Str(0);
    if (!sha.empty()) out.push_back(std::move(sha));
  }
  return out;
}

void JobStore::SetJobPriority(int64_t id, int priority) {
  std::lock_guard lock(mu_);
  Stmt(db_, "UPDATE jobs SET priority = ? WHERE id = ?").Bind(priority).Bind(id).Step();
}

}  // namespace lightfarm
