// The coordinator's core, without gRPC: the scheduler. It owns the jobs, their stages' task queues
// and the leases, under one lock; the planning I/O (scene, plan, stage combination, film) runs on
// the planner pool through JobPlanner (job_planner.h), and the durable state (JobStore +
// BlobStore) is what a restarted coordinator resumes from.
// The gRPC services (services.h) translate requests to these calls and FarmError to statuses.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "common/farm/farm_protocol.h"
#include "common/farm/job_types.h"
#include "common/render/render_job.h"
#include "common/render/serialize.h"
#include "coordinator/admission.h"
#include "coordinator/blob_store.h"
#include "coordinator/farm_error.h"
#include "coordinator/farm_metrics.h"
#include "coordinator/job_images.h"
#include "coordinator/job_planner.h"
#include "coordinator/job_progress.h"
#include "coordinator/job_snapshot.h"
#include "coordinator/job_store.h"
#include "coordinator/storage_guard.h"
#include "coordinator/thread_pool.h"

namespace lightfarm {


struct CoordinatorOptions {
  std::string state_dir;
  double lease_timeout_s = 30;       // a task whose worker stops heartbeating is re-queued
  int max_attempts = 3;              // K: a task fails after K failed attempts; a worker
                                     // that failed K tasks of a job is kept off it
  uint64_t max_blob_bytes = 1ull << 30;
  uint64_t max_result_bytes = 1ull << 31;
  int max_resolution = 16384;        // per axis
  uint64_t max_lights = 50'000'000;
  int max_spp = 4096;
  int max_active_jobs = 2;           // jobs planning or running at once
  int max_queued_jobs = 1000;        // unfinished jobs accepted
  int planner_threads = 1;
  // Below this much free space under state_dir the coordinator takes no new work (RESOURCE_EXHAUSTED
  // for submits and uploads, no leases, no planning) and resumes when space returns.
  uint64_t min_free_bytes = 100ull << 20;
  // A storage fault pauses the work that writes until space returns (a farm); false: it is an
  // ordinary error that fails the job (an embedded render).
  bool wait_for_space = true;
  // The share of tasks (chosen by a hash of job, pass, stage and task) run on a second worker
  // and compared bit for bit; a job's own `verify` asks for all of its tasks.
  double verify_share = 0;
  // Storage upkeep (a background thread): finished jobs older than this are deleted (0: kept
  // until `delete`); every gc_interval_s the blobs no job references and not written or asked
  // for within gc_grace_s are removed; the scrub re-hashes the store at this rate (0: off).
  double retain_finished_s = 0;
  double gc_interval_s = 600;
  double gc_grace_s = 3600;
  double scrub_mb_per_s = 16;
  // Start an empty farm on a state directory whose database is missing or empty although it
  // holds blobs (otherwise refused: the jobs those blobs belong to would be forgotten).
  bool fresh_state = false;
  // Embedded mode (cli/embedded_farm.h): every result the coordinator stores (a job's image,
  // or a progressive job's mean so far) handed over in process as the film's float image, so
  // the caller needs no EXR decode. Called on a planner thread, without the scheduler's lock,
  // after the result is stored and before the job is marked done.
  std::function<void(const std::string& job_id, const Image& image)> on_result;
};

// What a worker needs of a task's job to rebuild its plan (RebuildPlan): the scene, the pass's
// settings, the plan's clamp and the light and receiver sets by content hash.
struct LeasedJob {
  std::string job_id;
  SceneManifest manifest;
  RenderSettings settings;
  float clamp = 0;
  std::string lights_sha;
  std::string receivers_sha;
};

struct LeaseGrant {
  bool has_task = false;
  std::string lease_id;
  LeasedJob job;
  Bytes task;
  std::string artifact_sha;
};

// A preview of a running job's final stage: the film of the tiles finished so far.
struct JobResult {
  std::string stats_json;
  std::string exr_path;
  std::string exr_sha256;  // verified just before; the client checks the stream against it
};

class Coordinator {
 public:
  explicit Coordinator(CoordinatorOptions options);
  ~Coordinator();
  Coordinator(const Coordinator&) = delete;
  Coordinator& operator=(const Coordinator&) = delete;

  // Loads the state directory, resumes unfinished jobs and starts the lease/planning threads.
  void Start();
  // Stops threads (planning in flight finishes); state stays on disk for the next start.
  void Stop();
  // Refuse new jobs and leases (graceful drain before shutdown).
  void SetDraining() { draining_ = true; }

  BlobStore& blobs() { return *blobs_; }
  const CoordinatorOptions& options() const { return options_; }
  uint32_t lease_timeout_ms() const { return uint32_t(options_.lease_timeout_s * 1000.0); }

  // --- client API ---
  std::vector<std::string> FindMissingBlobs(const std::vector<std::string>& hashes) const;
  std::string Submit(const JobRequest& request);
  JobSnapshot GetJob(const std::string& job_id);
  std::vector<JobSnapshot> ListJobs();
  JobSnapshot Cancel(const std::string& job_id);
  // FAILED_PRECONDITION once the job has ended.
  JobSnapshot SetPriority(const std::string& job_id, int priority);
  // Workers registered or seen since this coordinator started, most recently seen first.
  std::vector<WorkerSnapshot> ListWorkers();
  JobResult GetResult(const std::string& job_id);
  // Forgets a job (cancelled first when unfinished): its rows, result and scratch files; its
  // blobs go at the next collection. NOT_FOUND for an unknown job.
  void Delete(const std::string& job_id);
  // Removes the blobs no job references that were not written or asked for within the grace
  // period; returns how many. Safe against a concurrent submit (FindMissingBlobs and Put
  // refresh a blob's time; Submit and the collection exclude each other).
  size_t CollectGarbage();
  // The preview of a job in its final stage when more than `have_tiles` tiles are done; false
  // when there is nothing newer (or the job is not in its final stage). Shared by all watchers.
  bool Preview(const std::string& job_id, uint64_t have_tiles, JobPreview* out);

  // --- worker API ---
  std::string RegisterWorker(const std::string& name, uint32_t protocol_version,
                             const std::string& software_version, int threads = 0);
  LeaseGrant Lease(const std::string& worker_id);
  bool Heartbeat(const std::string& worker_id, const std::string& lease_id);
  bool Complete(const std::string& worker_id, const std::string& lease_id, const Bytes& output);
  void Fail(const std::string& worker_id, const std::string& lease_id, const std::string& reason,
            bool hand_back);

  // Prometheus text exposition.
  std::string MetricsText();

  // A blob was found corrupted (and quarantined) outside the coordinator's own reads (FetchBlob):
  // the unfinished jobs that need it make it again.
  void OnBlobCorrupted(const std::string& sha256);

  // The state directory is (nearly) full: new work is refused until space returns.
  bool storage_full() const { return storage_.full(); }
  std::string StorageFullMessage() const { return storage_.FullMessage(); }

 private:
  using Clock = std::chrono::steady_clock;
  struct Task {
    Bytes spec;  // serialized SubMatrixTask
    size_t rows = 0;
    TaskStateCode state = TaskStateCode::kPending;
    int attempts = 0, failures = 0;
    int expiries = 0;  // leases that ran out: not counted as failures (a slow network is no evidence)
    std::string worker;
    Clock::time_point expiry;
    int64_t attempt_row = 0;
    std::string result_sha, last_error;
    bool verify = false;    // needs two workers' results, equal to the bit
    bool verified = false;  // it got them
    std::vector<std::pair<std::string, std::string>> candidates;  // (worker, result) not yet agreed on
    std::vector<std::string> failed_on;  // workers it failed on: retried elsewhere first
  };
  struct Job {
    int64_t id = 0;
    std::string name;
    int priority = 0;
    JobState state = JobState::kQueued;
    SceneManifest manifest;
    RenderSettings settings;
    int stage = 0, stage_count = 1;
    std::string stage_name;
    std::vector<Task> tasks;  // of the current stage
    size_t next_pending = 0;  // no task before it is pending
    size_t tasks_done = 0;
    std::shared_ptr<Plan> plan;
    PhaseTimes times;
    std::string lights_sha, receivers_sha, artifact_sha;
    float clamp = 0;
    std::string error;
    Clock::time_point started, stage_started, ended;
    size_t done_at_stage_start = 0;
    std::map<std::string, int> worker_failures;
    uint64_t attempts_total = 0, completions_total = 0;
    bool advancing = false;
    bool advance_paused = false;  // its stage finished while the disk was full: advanced on recovery
    int stage_high = 0;           // the highest stage it has run here (a repair may go back)
    int repairs = 0;              // times a corrupted blob sent it back to recompute
    std::string last_failure;     // the last task failure's reason
    uint64_t tasks_verified = 0;  // tasks two workers agreed on (every stage and pass)
    Clock::time_point blocked_since;  // since when no live worker may run it (epoch: it may run)
    double ended_unix = 0;            // when it ended (the retention policy counts from it)
    std::string result_sha, stats_json;
    std::shared_ptr<const JobPreview> preview;  // the latest one computed
    // Progressive jobs (progressive.h): the pass running, the finished ones accumulated, and
    // their noise (computed once per pass, not per status call).
    PassPlan passes;
    int pass = 0;
    std::shared_ptr<const PassAccumulator> acc;
    NoiseEstimate noise;
    Clock::time_point pass_started;
  };
  // What the dashboard shows of a worker; only its identity is durable (JobStore).
  struct WorkerInfo {
    std::string name, version;
    int threads = 0;
    bool seen = false;  // called since this coordinator started
    Clock::time_point last_seen;
    std::string lease;  // the lease it holds, if any
    uint64_t tasks_done = 0, tasks_failed = 0;
    std::string blocklisted;  // why it may run nothing here (outvoted); empty: trusted
  };
  // A call from a known worker (caller holds mu_).
  void SeenLocked(const std::string& worker_id);
  struct LeaseRef {
    int64_t job;
    int stage;
    uint32_t task;
    uint64_t attempt;  // the attempt's row in the store: increasing, so a later one was never granted
  };

  Job& FindJob(const std::string& job_id);  // throws NOT_FOUND; caller holds mu_
  JobSnapshot StatusLocked(const Job& job) const;
  void ProgressiveStatus(const Job& job, JobSnapshot* st) const;
  static bool ParseLease(const std::string& lease_id, LeaseRef* ref);
  Task* FindTaskLocked(const LeaseRef& ref, Job** job);
  // Worker calls on a lease: NOT_FOUND for a worker or job the coordinator does not know,
  // FAILED_PRECONDITION for a lease it never granted. A lease that was granted and has since
  // expired, been re-leased or finished passes (the callers answer "stop" or "duplicate").
  void CheckLeaseLocked(const std::string& worker_id, const std::string& lease_id, const LeaseRef& ref);
  void RecordFailureLocked(Job& job, uint32_t task_id, const std::string& worker,
                           const std::string& reason);
  // A lease ran out: the task goes back to the queue. The worker is not blamed (no evidence it
  // failed rather than the network); the task fails after 3 * max_attempts expiries (a task
  // that kills every worker that runs it).
  void ExpireLocked(Job& job, uint32_t task_id);
  // Why a running job with tasks to run makes no progress: no live worker, or every live
  // worker is kept off it (caller holds mu_); empty when some live worker may lease its tasks.
  std::string WaitingReasonLocked(const Job& job) const;
  // Some live, trusted worker other than `worker_id` may lease the job's tasks.
  bool OtherWorkerMayRunLocked(const Job& job, const std::string& worker_id) const;
  void FailJobLocked(Job& job, const std::string& error);
  // Blob `sha` of the job was found corrupted and quarantined: the job goes back to the earliest
  // stage that makes it again (plans are deterministic: what is recomputed has the same bits); a
  // scene file cannot be made again, so the job fails asking for it to be submitted again.
  void RepairLocked(Job& job, const std::string& sha, const std::string& what);
  // The job goes back to `stage` (planned again; tasks keep the stored results they still have).
  void RecomputeFromLocked(Job& job, int stage, const std::string& why);
  // Marks the tasks of the job's current stage that are verified (the job's verify, or the
  // --verify-share hash).
  void MarkVerifiedTasksLocked(Job& job) const;
  // A worker whose result two others outvoted runs nothing more here, and every result it gave
  // an unfinished job is computed again.
  void BlocklistLocked(const std::string& worker, const std::string& reason);
  // Store rows of a (re)planned stage: tasks done before keep their results while those exist.
  void ApplyRecords(std::vector<Task>& tasks, const std::vector<TaskRecord>& records) const;
  // The tick loop's check: pauses when space is low, resumes the paused work when it returns.
  void CheckStorageLocked();
  void MaybeStartPlanningLocked();
  void PlanJob(int64_t id);      // on the planner pool
  void AdvanceStage(int64_t id);  // on the planner pool: Combine + next stage, or the film
  void FinishJob(int64_t id, std::shared_ptr<Plan> plan, int stage);
  void TickLoop();
  // Storage upkeep: the scrub, the retention policy and the garbage collection.
  void UpkeepLoop();
  // Re-hashes stored blobs worth up to `bytes`, continuing where the last call stopped.
  void ScrubStep(uint64_t bytes);
  void ApplyRetention();
  static std::vector<Task> MakeTasks(const std::vector<SubMatrixTask>& specs);
  // The settings a job's current pass renders with: the job's, seeded PassSeed(seed, pass).
  static RenderSettings PassSettings(const Job& job);

  CoordinatorOptions options_;
  std::unique_ptr<JobStore> store_;
  std::unique_ptr<BlobStore> blobs_;
  std::unique_ptr<JobPlanner> job_planner_;
  std::unique_ptr<ThreadPool> planner_;
  std::mutex mu_;
  std::mutex preview_mu_;  // one preview computed at a time (they are throttled per watcher)
  std::map<int64_t, Job> jobs_;
  std::map<std::string, WorkerInfo> workers_;
  std::atomic<bool> draining_{false};
  bool stopping_ = false;
  std::condition_variable tick_cv_;
  std::thread ticker_;
  std::mutex gc_mu_;  // a collection and a submit's check of its blobs exclude each other
  std::thread upkeep_;
  std::vector<std::string> scrub_queue_;  // blobs left in this scrub pass (upkeep thread only)
  size_t scrub_next_ = 0;

  FarmCounters counters_;  // for /metrics (farm_metrics.h)
  StorageGuard storage_;   // the state directory's free space (storage_guard.h)
};

}  // namespace lightfarm
