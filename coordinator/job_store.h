// The coordinator's durable state: SQLite in WAL mode under --state-dir. Jobs, the artifact of
// each finished stage, tasks (state, attempts, result blob), every attempt, workers. A task's
// result is recorded as soon as it arrives, so a coordinator killed mid-job loses nothing that
// was acknowledged. Thread-safe (one connection behind a mutex). Opening runs SQLite's
// quick_check and refuses a damaged database; a full disk is StorageFull (storage_full.h).
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "common/farm/job_types.h"
#include "common/render/render_job.h"

struct sqlite3;
struct sqlite3_stmt;

namespace lightfarm {

enum class TaskStateCode : int { kPending = 0, kLeased = 1, kDone = 2 };

struct JobRecord {
  int64_t id = 0;
  std::string name;
  int priority = 0;
  JobState state = JobState::kQueued;
  SceneManifest manifest;   // the request as submitted (kept in the wire's encoding,
  RenderSettings settings;  // proto_convert.h, so an older store reads the same)
  int stage = 0;
  std::string error;
  double created = 0;       // unix seconds
  std::string result_sha, stats_json;  // a running progressive job: its passes so far
  int pass = 0;             // progressive jobs: the pass running (= passes finished)
  std::string accum_sha;    // progressive jobs: the PassAccumulator blob of the finished passes
  double finished = 0;      // unix seconds it ended (0: it has not, or ended before this was kept)
};

struct TaskRecord {
  int stage = 0;
  int task_id = 0;
  int state = 0;  // TaskStateCode
  int attempts = 0;
  int failures = 0;
  std::string result_sha;
  std::string last_error;
};

class JobStore {
 public:
  explicit JobStore(const std::string& path);
  ~JobStore();
  JobStore(const JobStore&) = delete;
  JobStore& operator=(const JobStore&) = delete;

  int64_t InsertJob(const JobRecord& job);
  void SetJobState(int64_t id, JobState state, const std::string& error);
  void SetJobStage(int64_t id, int stage);
  void FinishJob(int64_t id, JobState state, const std::string& result_sha, const std::string& stats_json);
  // A progressive job's pass finished: its accumulation and current result are recorded, and
  // the finished pass's tasks and artifacts give way to pass `next_pass`, stage 0 (one transaction).
  void FinishPass(int64_t id, int next_pass, const std::string& accum_sha, const std::string& result_sha,
                  const std::string& stats_json);
  void SetArtifact(int64_t id, int stage, const std::string& sha);
  std::map<int, std::string> Artifacts(int64_t id);

  // Creates rows for tasks 0..count-1 of a stage (existing rows are kept).
  void InsertTasks(int64_t id, int stage, int count);
  void UpdateTask(int64_t id, const TaskRecord& task);
  std::vector<TaskRecord> LoadTasks(int64_t id, int stage);  // by task id
  std::vector<TaskRecord> LoadAllTasks(int64_t id);          // by stage, task id

  // A task leased (its attempt row, returned, and its task row) and completed (its task row and
  // the attempt's end): one transaction each, on statements prepared once.
  int64_t RecordLease(int64_t job, const TaskRecord& task, const std::string& worker);
  void RecordCompletion(int64_t job, const TaskRecord& task, int64_t attempt);

  void EndAttempt(int64_t attempt, const std::string& outcome);

  std::vector<JobRecord> LoadJobs();
  void SetJobPriority(int64_t id, int priority);
  // Every row of the job (its tasks, attempts and artifacts too), in one transaction.
  void DeleteJob(int64_t id);
  // Rows of tasks, attempts and artifacts whose job is gone.
  void DeleteOrphans();
  // Every blob the stored jobs name: results, accumulations, task results, artifacts.
  std::vector<std::string> ReferencedBlobs();

  struct WorkerRecord {
    std::string id, name, version;
    int threads = 0;
    std::string blocklisted;  // why it may run nothing here; empty: trusted
  };
  void UpsertWorker(const WorkerRecord& worker);
  void SetWorkerBlocklisted(const std::string& id, const std::string& reason);
  // (stage, task) of every task of the job whose result `worker` delivered and the job kept.
  std::vector<std::pair<int, int>> TasksDoneBy(int64_t job, const std::string& worker);
  std::vector<WorkerRecord> LoadWorkers();

 private:
  // Settings, the integrity check and the schema (created, or migrated from older versions).
  void Initialize(const std::string& path);
  void Exec(const char* sql);
  // Caller holds mu_.
  sqlite3_stmt* Prepared(const char* sql);
  void WriteTask(int64_t job, const TaskRecord& task);
  void WriteAttemptEnd(int64_t attempt, const std::string& outcome);
  std::mutex mu_;
  sqlite3* db_ = nullptr;
  std::map<const char*, sqlite3_stmt*> prepared_;  // by the statement literal's address
};

}  // namespace lightfarm
