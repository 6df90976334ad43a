#include "coordinator/coordinator.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <sstream>

#include "common/render/stage_engine.h"
#include "common/util/error.h"

namespace lightfarm {

namespace fs = std::filesystem;
using Code = FarmError::Code;

namespace {

// `text` with every byte that is not part of a well-formed UTF-8 sequence replaced by '?'.
// Proto3 string fields must be valid UTF-8: an error message quoting a binary scene file would
// otherwise make every JobStatus holding it unparseable for the client (GetJob, ListJobs and
// WatchJob of that job all failed).
std::string ValidUtf8(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  const auto* s = reinterpret_cast<const unsigned char*>(text.data());
  const size_t n = text.size();
  for (size_t i = 0; i < n;) {
    const unsigned c = s[i];
    size_t len = 0;
    unsigned lo = 0x80, hi = 0xBF;  // range of the second byte (overlongs, surrogates, > U+10FFFF)
    if (c < 0x80) len = 1;
    else if (c >= 0xC2 && c <= 0xDF) len = 2;
    else if (c >= 0xE0 && c <= 0xEF) {
      len = 3;
      if (c == 0xE0) lo = 0xA0;
      if (c == 0xED) hi = 0x9F;
    } else if (c >= 0xF0 && c <= 0xF4) {
      len = 4;
      if (c == 0xF0) lo = 0x90;
      if (c == 0xF4) hi = 0x8F;
    }
    bool ok = len > 0 && i + len <= n;
    for (size_t k = 1; ok && k < len; ++k) {
      const unsigned b = s[i + k];
      ok = k == 1 ? (b >= lo && b <= hi) : (b >= 0x80 && b <= 0xBF);
    }
    if (ok) {
      out.append(text, i, len);
      i += len;
    } else {
      out += '?';
      ++i;
    }
  }
  return out;
}

double Seconds(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

double UnixNow() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::string RandomId() {
  std::random_device rd;
  std::ostringstream os;
  os << std::hex << rd() << rd();
  return os.str();
}

}  // namespace

namespace {

// Blobs already in a state directory's store (counted up to `limit`).
size_t StoredBlobs(const std::string& blob_dir, size_t limit) {
  size_t n = 0;
  std::error_code ec;
  for (auto it = fs::directory_iterator(blob_dir, ec); !ec && it != fs::directory_iterator() && n < limit;
       it.increment(ec))
    n += it->is_regular_file(ec) && IsSha256Hex(it->path().filename().string());
  return n;
}

}  // namespace

Coordinator::Coordinator(CoordinatorOptions options)
    : options_(std::move(options)),
      storage_(options_.state_dir, options_.min_free_bytes, options_.wait_for_space, &counters_.storage_full) {
  if (options_.state_dir.empty()) throw std::invalid_argument("coordinator: --state-dir is required");
  fs::create_directories(options_.state_dir);
  // A database that is gone or empty beside a store of blobs is a lost database, not a new
  // farm: starting would forget every job those blobs belong to and reuse their ids.
  const std::string db = options_.state_dir + "/state.sqlite";
  std::error_code ec;
  const bool db_empty = !fs::exists(db, ec) || fs::file_size(db, ec) == 0;
  if (db_empty) {
    const size_t blobs = StoredBlobs(options_.state_dir + "/blobs", 1000);
    if (blobs > 0 && !options_.fresh_state)
      throw std::runtime_error("state directory " + options_.state_dir + " holds " +
                               (blobs >= 1000 ? "1000 or more" : std::to_string(blobs)) + " blobs but its database " +
                               db + (fs::exists(db, ec) ? " is empty" : " is missing") +
                               ": the jobs they belong to would be forgotten. Restore the database from a "
                               "backup, or pass --fresh-state to start an empty farm here on purpose");
    if (blobs > 0)
      spdlog::warn("state directory {}: starting an empty farm beside {} existing blobs (--fresh-state)",
                   options_.state_dir, blobs);
  }
  store_ = std::make_unique<JobStore>(db);
  blobs_ = std::make_unique<BlobStore>(options_.state_dir + "/blobs", options_.max_blob_bytes);
  job_planner_ = std::make_unique<JobPlanner>(
      options_.state_dir, PlanLimits{options_.max_resolution, options_.max_spp}, *store_, *blobs_);
}

Coordinator::~Coordinator() { Stop(); }

void Coordinator::Start() {
  planner_ = std::make_unique<ThreadPool>(std::max(1, options_.planner_threads));
  std::lock_guard lock(mu_);
  for (const JobStore::WorkerRecord& w : store_->LoadWorkers())
  {
    WorkerInfo& info = workers_[w.id];
    info.name = w.name;
    info.version = w.version;
    info.threads = w.threads;
    info.blocklisted = w.blocklisted;
  }
  // Every unfinished job is planned again (deterministic) and continues at its stage; the
  // tasks already done keep their results (JobStore), so none is recomputed.
  for (JobRecord& r : store_->LoadJobs()) {
    Job job;
    job.id = r.id;
    job.name = r.name;
    job.priority = r.priority;
    job.state = r.state;
    // The store keeps the request as submitted (the wire's bytes); the scheduler, plain types.
    job.manifest = std::move(r.manifest);
    job.settings = std::move(r.settings);
    job.stage = r.stage;
    job.error = r.error;
    job.result_sha = r.result_sha;
    job.stats_json = r.stats_json;
    job.ended_unix = r.finished > 0 ? r.finished : r.created;
    job.passes = job.settings.progressive;
    if (job.passes.progressive()) {
      PassAccumulator acc;
      try {
        if (!r.accum_sha.empty()) acc = PassAccumulator::Deserialize(blobs_->Get(r.accum_sha));
        if (int(acc.passes()) != r.pass)
          throw std::runtime_error("it holds " + std::to_string(acc.passes()) + " passes, the job " +
                                   std::to_string(r.pass));
      } catch (const std::exception& e) {
        // The store's tasks belong to pass r.pass: without its accumulation nothing can resume.
        if (!IsTerminal(job.state)) {
          job.state = JobState::kFailed;
          job.error = std::string("the accumulation of the finished passes is unreadable: ") + e.what();
          store_->SetJobState(job.id, job.state, job.error);
        }
        acc = PassAccumulator();
      }
      job.pass = int(acc.passes());
      job.noise = acc.Noise();
      job.acc = std::make_shared<const PassAccumulator>(std::move(acc));
    }
    if (!IsTerminal(job.state)) {
      if (job.state != JobState::kQueued)
        spdlog::info("job {}: resuming at stage {}", job.id, job.stage);
      job.state = JobState::kQueued;
    }
    jobs_.emplace(job.id, std::move(job));
  }
  MaybeStartPlanningLocked();
  ticker_ = std::thread([this] { TickLoop(); });
  upkeep_ = std::thread([this] { UpkeepLoop(); });
}

void Coordinator::Stop() {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return;
    stopping_ = true;
  }
  tick_cv_.notify_all();
  if (ticker_.joinable()) ticker_.join();
  if (upkeep_.joinable()) upkeep_.join();
  if (planner_) planner_->Stop();
}

// --- client API ---------------------------------------------------------------------------------

std::vector<std::string> Coordinator::FindMissingBlobs(const std::vector<std::string>& hashes) const {
  std::vector<std::string> missing;
  for (const std::string& h : hashes) {
    if (!IsSha256Hex(h)) throw FarmError(Code::kInvalidArgument, "not a SHA-256 hex digest: \"" + h.substr(0, 80) + "\"");
    if (!blobs_->Has(h))
      missing.push_back(h);
    else
      blobs_->Touch(h);  // the submit that follows needs it: kept through the collection's grace period
  }
  return missing;
}

std::string Coordinator::Submit(const JobRequest& req) {
  if (draining_) throw FarmError(Code::kUnavailable, "coordinator is shutting down; submit again later");
  if (storage_.full() || storage_.Low()) throw FarmError(Code::kResourceExhausted, storage_.FullMessage());
  // From the check that its files are stored to the job's insertion, no collection runs.
  std::lock_guard gc(gc_mu_);
  CheckSubmission(req, AdmissionLimits{options_.max_resolution, options_.max_lights, options_.max_spp},
                  [this](const std::string& sha) { return blobs_->Has(sha); });
  std::lock_guard lock(mu_);
  int unfinished = 0;
  for (const auto& [id, j] : jobs_) unfinished += !IsTerminal(j.state);
  if (unfinished >= options_.max_queued_jobs)
    throw FarmError(Code::kResourceExhausted, "the queue is full (" + std::to_string(unfinished) +
                                                  " unfinished jobs; limit --max-queued-jobs)");
  JobRecord r;
  r.name = req.name;
  r.priority = req.priority;
  r.state = JobState::kQueued;
  r.manifest = req.manifest;
  r.settings = req.settings;
  Job job;
  try {
    job.id = store_->InsertJob(r);
  } catch (const StorageFull& e) {
    storage_.NoteFull(e.what());
    throw FarmError(Code::kResourceExhausted, storage_.FullMessage());
  }
  job.name = req.name;
  job.priority = req.priority;
  job.manifest = req.manifest;
  job.settings = req.settings;
  job.passes = job.settings.progressive;
  if (job.passes.progressive()) job.acc = std::make_shared<const PassAccumulator>();
  const int64_t id = job.id;
  jobs_.emplace(id, std::move(job));
  ++counters_.submitted;
  spdlog::info("job {}: submitted ({}, {} files)", id, req.settings.method, req.manifest.files.size());
  MaybeStartPlanningLocked();
  return std::to_string(id);
}

Coordinator::Job& Coordinator::FindJob(const std::string& job_id) {
  int64_t id = 0;
  try {
    size_t used = 0;
    id = std::stoll(job_id, &used);
    if (used != job_id.size()) throw std::invalid_argument(job_id);
  } catch (const std::exception&) {
    throw FarmError(Code::kInvalidArgument, "job id \"" + job_id.substr(0, 80) + "\" is not a number");
  }
  auto it = jobs_.find(id);
  if (it == jobs_.end()) throw FarmError(Code::kNotFound, "no job " + job_id);
  return it->second;
}

JobSnapshot Coordinator::StatusLocked(const Job& job) const {
  JobSnapshot st;
  st.job_id = std::to_string(job.id);
  st.state = job.state;
  st.name = job.name;
  st.priority = job.priority;
  st.method = job.settings.method;
  st.stage = job.stage;
  st.stage_count = job.stage_count;
  st.stage_name = job.stage_name;
  st.tasks_done = job.tasks_done;
  st.tasks_total = job.tasks.size();
  st.error = ValidUtf8(job.error);
  st.attempts = job.attempts_total;
  st.tasks_completed_total = job.completions_total;
  st.tasks_verified = job.tasks_verified;
  st.eta_s = -1;
  if (job.state == JobState::kRunning || job.state == JobState::kPlanning) {
    const auto now = Clock::now();
    st.elapsed_s = Seconds(now - job.started);
    if (job.state == JobState::kRunning)
      st.eta_s = StageEtaSeconds(job.tasks_done, job.tasks.size(), job.done_at_stage_start,
                                 job.stage + 1 == job.stage_count, Seconds(now - job.stage_started));
  } else if (job.state == JobState::kDone) {
    st.eta_s = 0;
  }
  // A job that ended under this coordinator: how long it ran (one restored from the store: 0).
  if (IsTerminal(job.state) && job.ended > job.started && job.started != Clock::time_point{})
    st.elapsed_s = Seconds(job.ended - job.started);
  st.scene = job.manifest.root;
  st.scene_sha256 = job.manifest.RootSha256();
  if (job.passes.progressive()) ProgressiveStatus(job, &st);
  if (!IsTerminal(job.state) && storage_.full())
    st.waiting = storage_.FullMessage();
  else
    st.waiting = WaitingReasonLocked(job);
  return st;
}

void Coordinator::ProgressiveStatus(const Job& job, JobSnapshot* st) const {
  const uint32_t done = job.acc ? job.acc->passes() : 0;
  st->progressive = true;
  st->passes_done = done;
  st->passes_total = job.passes.passes;
  st->noise_rel_stderr = std::isfinite(job.noise.rel_stderr) ? job.noise.rel_stderr : -1;
  st->noise_p90_rel_stderr = std::isfinite(job.noise.p90_rel_stderr) ? job.noise.p90_rel_stderr : -1;
  if (IsTerminal(job.state) || done == 0) return;  // the first pass's ETA is the stage's (above)
  st->eta_s = PassesEtaSeconds(job.passes, *job.acc, job.noise, Seconds(Clock::now() - job.pass_started));
}

JobSnapshot Coordinator::GetJob(const std::string& job_id) {
  std::lock_guard lock(mu_);
  return StatusLocked(FindJob(job_id));
}

std::vector<JobSnapshot> Coordinator::ListJobs() {
  std::lock_guard lock(mu_);
  std::vector<JobSnapshot> out;
  for (const auto& [id, job] : jobs_) out.push_back(StatusLocked(job));
  return out;
}

JobSnapshot Coordinator::Cancel(const std::string& job_id) {
  std::lock_guard lock(mu_);
  Job& job = FindJob(job_id);
  if (!IsTerminal(job.state)) {
    store_->SetJobState(job.id, JobState::kCancelled, "cancelled");  // a full disk: refused, unchanged
    job.state = JobState::kCancelled;
    job.ended = Clock::now();
    job.ended_unix = UnixNow();
    job.error = "cancelled";
    job.plan.reset();
    spdlog::info("job {}: cancelled", job.id);
    MaybeStartPlanningLocked();
  }
  return StatusLocked(job);
}

JobSnapshot Coordinator::SetPriority(const std::string& job_id, int priority) {
  std::lock_guard lock(mu_);
  Job& job = FindJob(job_id);
  if (IsTerminal(job.state))
    throw FarmError(Code::kFailedPrecondition,
                    "job " + job_id + " is " + JobStateName(job.state) + ": its priority no longer matters");
  if (job.priority != priority) {
    store_->SetJobPriority(job.id, priority);
    spdlog::info("job {}: priority {} -> {}", job.id, job.priority, priority);
    job.priority = priority;
  }
  return StatusLocked(job);
}

void Coordinator::SeenLocked(const std::string& worker_id) {
  WorkerInfo& w = workers_[worker_id];
  w.seen = true;
  w.last_seen = Clock::now();
}

std::vector<WorkerSnapshot> Coordinator::ListWorkers() {
  std::lock_guard lock(mu_);
  const auto now = Clock::now();
  std::vector<std::pair<double, WorkerSnapshot>> rows;
  for (const auto& [id, w] : workers_) {
    if (!w.seen) continue;
    WorkerSnapshot st;
    st.worker_id = id;
    st.name = w.name;
    st.version = w.version;
    st.threads = w.threads;
    const double ago = Seconds(now - w.last_seen);
    st.last_seen_s = ago;
    st.alive = ago < 2.0 * options_.lease_timeout_s;
    st.tasks_done = w.tasks_done;
    st.tasks_failed = w.tasks_failed;
    st.blocklisted = w.blocklisted;
    // The lease it was granted, while the task is still its own (an expired one was re-queued).
    LeaseRef ref;
    Job* job = nullptr;
    if (!w.lease.empty() && ParseLease(w.lease, &ref)) {
      const Task* task = FindTaskLocked(ref, &job);
      if (task && task->state == TaskStateCode::kLeased && task->worker == id) {
        st.lease_id = w.lease;
        st.job_id = std::to_string(ref.job);
      }
    }
    for (const auto& [job_id, j] : jobs_) {
      auto f = j.worker_failures.find(id);
      if (!IsTerminal(j.state) && f != j.worker_failures.end() && f->second >= options_.max_attempts)
        st.blocked_jobs.push_back(std::to_string(job_id));
    }
    rows.emplace_back(ago, std::move(st));
  }
  std::stable_sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<WorkerSnapshot> out;
  for (auto& [ago, st] : rows) out.push_back(std::move(st));
  return out;
}

JobResult Coordinator::GetResult(const std::string& job_id) {
  std::lock_guard lock(mu_);
  Job& job = FindJob(job_id);
  // A progressive job has a result as soon as one pass is done: the mean of its passes so far,
  // while it runs and after it is cancelled.
  const bool partial = job.passes.progressive() && !job.result_sha.empty();
  if (job.state != JobState::kDone && !partial)
    throw FarmError(Code::kFailedPrecondition, "job " + job_id + " is " + JobStateName(job.state) +
                                                   (job.error.empty() ? "" : " (" + job.error + ")") +
                                                   ", not done");
  if (!blobs_->Has(job.result_sha))
    throw FarmError(Code::kNotFound, "the result image of job " + job_id + " is missing from the blob store");
  // Re-hashed before it is served: a result whose bytes changed on disk is quarantined and
  // reported, never streamed as the job's image. A finished job is then made again from its
  // stored tasks (the same bits: plans are deterministic).
  if (!blobs_->Verify(job.result_sha)) {
    const std::string sha = job.result_sha;
    std::string next = "render the job again";
    if (job.state == JobState::kDone && !job.passes.progressive()) {
      job.result_sha.clear();
      job.state = JobState::kRunning;  // RepairLocked re-plans a running job
      RepairLocked(job, sha, "its result image is corrupted on the coordinator's disk (quarantined)");
      if (!IsTerminal(job.state)) next = "it is being made again from its stored tasks; fetch it when it is done";
    }
    throw FarmError(Code::kDataLoss, "the result image of job " + job_id +
                                         " is corrupted on the coordinator's disk (blob " + sha + ", quarantined); " + next);
  }
  return JobResult{job.stats_json, blobs_->Path(job.result_sha), job.result_sha};
}

bool Coordinator::Preview(const std::string& job_id, uint64_t have_tiles, JobPreview* out) {
  std::lock_guard compute(preview_mu_);
  std::shared_ptr<Plan> plan;
  std::shared_ptr<const PassAccumulator> acc;
  std::vector<std::pair<Bytes, std::string>> done;  // (task spec, result blob) of finished tiles
  int64_t id = 0;
  uint64_t version = 0;
  {
    std::lock_guard lock(mu_);
    Job& job = FindJob(job_id);
    if (IsTerminal(job.state)) return false;
    if (job.acc && job.acc->passes() > 0) {
      // A progressive job with finished passes shows their mean: a new preview per pass.
      version = uint64_t(job.acc->passes()) << 32;
      acc = job.acc;
    } else {
      if (job.state != JobState::kRunning || job.stage + 1 != job.stage_count || !job.plan) return false;
      version = job.tasks_done;
      plan = job.plan;
      for (const Task& t : job.tasks)
        if (t.state == TaskStateCode::kDone) done.emplace_back(t.spec, t.result_sha);
    }
    if (version <= have_tiles) return false;
    if (job.preview && job.preview->tiles == version) {
      *out = *job.preview;
      return true;
    }
    id = job.id;
  }
  // Assembled outside the lock.
  std::shared_ptr<JobPreview> preview;
  try {
    preview = std::make_shared<JobPreview>(acc ? job_planner_->Preview(id, acc->Mean(), version)
                                               : job_planner_->Preview(id, *plan, done));
  } catch (const BlobCorrupted& e) {
    std::lock_guard lock(mu_);
    auto it = jobs_.find(id);
    if (it != jobs_.end() && it->second.state == JobState::kRunning) RepairLocked(it->second, e.sha256(), e.what());
    return false;
  }
  {
    std::lock_guard lock(mu_);
    auto it = jobs_.find(id);
    if (it != jobs_.end()) it->second.preview = preview;
  }
  *out = *preview;
  return true;
}

// --- worker API ---------------------------------------------------------------------------------

std::string Coordinator::RegisterWorker(const std::string& name, uint32_t protocol_version,
                                        const std::string& software_version, int threads) {
  if (protocol_version != kWorkerProtocolVersion)
    throw FarmError(Code::kFailedPrecondition,
                    "worker \"" + name + "\" speaks worker protocol " + std::to_string(protocol_version) +
                        " (lightfarm " + software_version + "), this coordinator speaks protocol " +
                        std::to_string(kWorkerProtocolVersion) + " (lightfarm " LIGHTFARM_VERSION
                        "): upgrade the worker to the coordinator's version");
  std::string id = "w-" + RandomId();
  try {
    store_->UpsertWorker({id, name, software_version, threads});
  } catch (const StorageFull& e) {
    // Only the dashboard's memory of the worker is durable: it works unrecorded meanwhile.
    storage_.NoteFull(e.what());
  }
  std::lock_guard lock(mu_);
  workers_[id] = WorkerInfo{name, software_version, threads};
  SeenLocked(id);
  spdlog::info("worker {} registered as {}", name, id);
  return id;
}

bool Coordinator::ParseLease(const std::string& lease_id, LeaseRef* ref) {
  // "<job>.<stage>.<task>.<attempt>"
  unsigned long long job = 0, attempt = 0;
  int stage = 0;
  unsigned task = 0;
  char tail = 0;
  if (std::sscanf(lease_id.c_str(), "%llu.%d.%u.%llu%c", &job, &stage, &task, &attempt, &tail) != 4)
    return false;
  *ref = LeaseRef{int64_t(job), stage, task, uint64_t(attempt)};
  return true;
}

void Coordinator::CheckLeaseLocked(const std::string& worker_id, const std::string& lease_id,
                                   const LeaseRef& ref) {
  if (!workers_.count(worker_id))
    throw FarmError(Code::kNotFound, "unknown worker \"" + worker_id.substr(0, 80) + "\"; register again");
  auto it = jobs_.find(ref.job);
  if (it == jobs_.end())
    throw FarmError(Code::kNotFound, "lease " + lease_id + " names job " + std::to_string(ref.job) +
                                         ", which this coordinator does not have");
  const Job& job = it->second;
  const auto never_granted = [&] {
    return FarmError(Code::kFailedPrecondition, "lease " + lease_id + " was never granted");
  };
  if (ref.stage > std::max(job.stage, job.stage_high) || ref.stage < 0) throw never_granted();
  if (job.state != JobState::kRunning || ref.stage != job.stage) return;  // over (or repaired): stale
  if (ref.task >= job.tasks.size()) throw never_granted();
  const Task& task = job.tasks[ref.task];
  // attempt_row is 0 for tasks restored after a restart: their leases cannot be told apart.
  if (task.attempts == 0 || (task.attempt_row > 0 && ref.attempt > uint64_t(task.attempt_row)))
    throw never_granted();
}

Coordinator::Task* Coordinator::FindTaskLocked(const LeaseRef& ref, Job** job_out) {
  auto it = jobs_.find(ref.job);
  if (it == jobs_.end()) return nullptr;
  Job& job = it->second;
  *job_out = &job;
  if (job.state != JobState::kRunning || job.stage != ref.stage || ref.task >= job.tasks.size())
    return nullptr;
  return &job.tasks[ref.task];
}

LeaseGrant Coordinator::Lease(const std::string& worker_id) {
  ++counters_.lease_polls;
  std::lock_guard lock(mu_);
  if (!workers_.count(worker_id))
    throw FarmError(Code::kNotFound, "unknown worker " + worker_id + "; register again");
  SeenLocked(worker_id);
  WorkerInfo& worker = workers_[worker_id];
  worker.lease.clear();  // a worker asks for a task when it holds none
  if (!worker.blocklisted.empty())
    throw FarmError(Code::kFailedPrecondition, "this worker is blocklisted on this farm: " + worker.blocklisted);
  LeaseGrant grant;
  if (draining_ || stopping_ || storage_.full()) return grant;  // a full disk: no new work until space returns
  // Highest priority first, then the oldest job; within a job the lowest task id.
  Job* best = nullptr;
  size_t best_task = 0;
  for (auto& [id, job] : jobs_) {
    if (job.state != JobState::kRunning || job.advancing) continue;
    if (best && job.priority <= best->priority) continue;
    auto wf = job.worker_failures.find(worker_id);
    if (wf != job.worker_failures.end() && wf->second >= options_.max_attempts) continue;
    // Tasks before the cursor are not pending (a task that becomes pending again moves it back):
    // a lease costs O(1) amortized however many tasks the stage has.
    while (job.next_pending < job.tasks.size() && job.tasks[job.next_pending].state != TaskStateCode::kPending)
      ++job.next_pending;
    // A task being verified goes to a worker that has not given a result for it yet; a task
    // that failed on this worker goes to another one first (one bad worker must not spend a
    // task's attempts alone), and back to it only when no other worker may run it.
    size_t retry = job.tasks.size();
    for (size_t t = job.next_pending; t < job.tasks.size(); ++t) {
      const Task& task = job.tasks[t];
      if (task.state != TaskStateCode::kPending) continue;
      if (std::any_of(task.candidates.begin(), task.candidates.end(),
                      [&](const auto& c) { return c.first == worker_id; }))
        continue;
      if (std::find(task.failed_on.begin(), task.failed_on.end(), worker_id) != task.failed_on.end()) {
        retry = std::min(retry, t);
        continue;
      }
      best = &job;
      best_task = t;
      break;
    }
    if (best != &job && retry < job.tasks.size() && !OtherWorkerMayRunLocked(job, worker_id)) {
      best = &job;
      best_task = retry;
    }
  }
  if (!best) return grant;
  Job& job = *best;
  Task& task = job.tasks[best_task];
  task.state = TaskStateCode::kLeased;
  task.worker = worker_id;
  task.expiry = Clock::now() + std::chrono::milliseconds(lease_timeout_ms());
  ++task.attempts;
  ++job.attempts_total;
  try {
    task.attempt_row = store_->RecordLease(job.id, TaskRecord{job.stage, int(best_task), int(task.state),
                                                              task.attempts, task.failures, task.result_sha,
                                                              task.last_error},
                                           worker_id);
  } catch (const StorageFull& e) {
    task.state = TaskStateCode::kPending;  // not granted: the task stays as it was
    task.worker.clear();
    --task.attempts;
    --job.attempts_total;
    storage_.NoteFull(e.what());
    return grant;
  }
  ++counters_.leases;
  grant.has_task = true;
  grant.lease_id = std::to_string(job.id) + "." + std::to_string(job.stage) + "." +
                   std::to_string(best_task) + "." + std::to_string(task.attempt_row);
  worker.lease = grant.lease_id;
  grant.job = LeasedJob{std::to_string(job.id), job.manifest, PassSettings(job), float(job.clamp),
                        job.lights_sha, job.receivers_sha};
  grant.task = task.spec;
  grant.artifact_sha = job.artifact_sha;
  return grant;
}

bool Coordinator::Heartbeat(const std::string& worker_id, const std::string& lease_id) {
  LeaseRef ref;
  if (!ParseLease(lease_id, &ref)) throw FarmError(Code::kInvalidArgument, "malformed lease id");
  std::lock_guard lock(mu_);
  CheckLeaseLocked(worker_id, lease_id, ref);
  SeenLocked(worker_id);
  Job* job = nullptr;
  Task* task = FindTaskLocked(ref, &job);
  if (!task || task->state == TaskStateCode::kDone) return false;
  if (task->state == TaskStateCode::kLeased && task->worker != worker_id) return false;
  // Pending (the lease expired, or the coordinator restarted): the worker keeps it.
  task->state = TaskStateCode::kLeased;
  task->worker = worker_id;
  task->expiry = Clock::now() + std::chrono::milliseconds(lease_timeout_ms());
  return true;
}

bool Coordinator::Complete(const std::string& worker_id, const std::string& lease_id,
                           const Bytes& bytes) {
  LeaseRef ref;
  if (!ParseLease(lease_id, &ref)) throw FarmError(Code::kInvalidArgument, "malformed lease id");
  std::shared_ptr<Plan> plan;
  Bytes spec;
  bool final_stage = false;
  {
    std::lock_guard lock(mu_);
    CheckLeaseLocked(worker_id, lease_id, ref);
    Job* job = nullptr;
    Task* task = FindTaskLocked(ref, &job);
    if (!task || task->state == TaskStateCode::kDone) {
      ++counters_.duplicates;
      return false;  // a duplicate or stale completion: harmless
    }
    if (!workers_[worker_id].blocklisted.empty())
      throw FarmError(Code::kFailedPrecondition, "this worker is blocklisted on this farm: " + workers_[worker_id].blocklisted);
    spec = task->spec;
    plan = job->plan;
    final_stage = job->stage + 1 == job->stage_count;
  }
  // Validate outside the lock; a malformed result is the task's failure, not the coordinator's.
  std::string problem;
  try {
    TaskOutput out = DeserializeTaskOutput(bytes);
    if (final_stage) {
      const SubMatrixTask task = DeserializeTask(spec);
      if (plan)
        problem = CheckFinalOutput(*plan, task, out);
      else if (out.row_sums.size() != task.rows.size())  // no plan to say more (never expected)
        problem = "result has " + std::to_string(out.row_sums.size()) + " rows, the task has " +
                  std::to_string(task.rows.size());
      // Radiance and filter weights are finite: a NaN or infinity is a broken worker, never
      // a pixel (the film would drop it and show the hole only in its stats).
      for (size_t i = 0; problem.empty() && i < out.row_sums.size(); ++i) {
        const RGBAccum& v = out.row_sums[i];
        if (!std::isfinite(v.r) || !std::isfinite(v.g) || !std::isfinite(v.b))
          problem = "result row " + std::to_string(i) + " is not finite";
      }
      for (size_t i = 0; problem.empty() && i < out.row_weights.size(); ++i)
        if (!std::isfinite(out.row_weights[i])) problem = "result row weight " + std::to_string(i) + " is not finite";
    }
  } catch (const SerializeError& e) {
    problem = std::string("malformed result: ") + e.what();
  }
  std::string sha;
  const auto storage_full = [&](const StorageFull& e) {
    storage_.NoteFull(e.what());
    // UNAVAILABLE: the worker keeps the result and delivers it again.
    return FarmError(Code::kUnavailable, "the coordinator cannot store the result now: " + storage_.FullMessage());
  };
  try {
    if (problem.empty()) sha = blobs_->Put(bytes);
  } catch (const StorageFull& e) {
    throw storage_full(e);
  }

  std::lock_guard lock(mu_);
  SeenLocked(worker_id);
  WorkerInfo& worker = workers_[worker_id];
  if (worker.lease == lease_id) worker.lease.clear();
  Job* job = nullptr;
  Task* task = FindTaskLocked(ref, &job);
  if (!task || task->state == TaskStateCode::kDone) {
    ++counters_.duplicates;
    return false;
  }
  if (!problem.empty()) {
    // Only the lease's holder fails the task: a malformed result from any other worker (a stale
    // or borrowed lease id) must not count towards max_attempts and fail the job.
    if (task->state == TaskStateCode::kLeased && task->worker == worker_id)
      RecordFailureLocked(*job, ref.task, worker_id, problem);
    throw FarmError(Code::kInvalidArgument, problem);
  }
  // A verified task is done when two workers' results are the same bits (tasks are
  // deterministic); until then each result is a candidate and the task goes to another worker.
  std::vector<std::string> outvoted;
  if (task->verify && !task->verified) {
    if (std::any_of(task->candidates.begin(), task->candidates.end(),
                    [&](const auto& c) { return c.first == worker_id; })) {
      ++counters_.duplicates;
      return false;
    }
    task->candidates.emplace_back(worker_id, sha);
    std::map<std::string, int> votes;
    for (const auto& c : task->candidates) ++votes[c.second];
    std::string agreed;
    for (const auto& [result, n] : votes)
      if (n >= 2) agreed = result;
    const std::string what = "task " + std::to_string(ref.task) + " of stage " + std::to_string(job->stage) +
                             " of job " + std::to_string(job->id);
    if (agreed.empty()) {
      std::string who;
      for (const auto& c : task->candidates) who += (who.empty() ? "" : ", ") + c.first;
      if (task->candidates.size() >= 3) {
        FailJobLocked(*job, what + " gave " + std::to_string(task->candidates.size()) + " different results on workers " +
                                who + ": its computation is not deterministic, or several workers are faulty");
        return true;
      }
      if (task->candidates.size() == 2) {
        ++counters_.mismatches;
        spdlog::warn("{}: the results of workers {} differ; a third worker decides", what, who);
      }
      try {
        if (task->attempt_row) store_->EndAttempt(task->attempt_row, "done: awaiting verification");
      } catch (const StorageFull& e) {
        storage_.NoteFull(e.what());
      }
      task->state = TaskStateCode::kPending;
      task->worker.clear();
      job->next_pending = std::min<size_t>(job->next_pending, ref.task);
      ++worker.tasks_done;
      ++job->completions_total;
      ++counters_.completed;
      return true;
    }
    for (const auto& c : task->candidates)
      if (c.second != agreed) outvoted.push_back(c.first);
    sha = agreed;
    task->verified = true;
    task->candidates.clear();
    ++job->tasks_verified;
    ++counters_.verified;
  }
  try {
    store_->RecordCompletion(job->id,
                            TaskRecord{job->stage, int(ref.task), int(TaskStateCode::kDone), task->attempts,
                                       task->failures, sha, task->last_error},
                            task->attempt_row);
  } catch (const StorageFull& e) {
    throw storage_full(e);
  }
  task->state = TaskStateCode::kDone;
  task->result_sha = sha;
  task->worker = worker_id;
  ++worker.tasks_done;
  ++job->tasks_done;
  ++job->completions_total;
  ++counters_.completed;
  const int64_t id = job->id;
  for (const std::string& liar : outvoted)
    BlocklistLocked(liar, "its result for task " + std::to_string(ref.task) + " of stage " + std::to_string(ref.stage) +
                              " of job " + std::to_string(id) + " differed from two other workers' (bit for bit)");
  Job& same = jobs_.at(id);  // blocklisting may have sent it back to an earlier stage
  if (same.state == JobState::kRunning && same.tasks_done == same.tasks.size() && !same.advancing) {
    same.advancing = true;
    planner_->Submit([this, id] { AdvanceStage(id); });
  }
  return true;
}

void Coordinator::Fail(const std::string& worker_id, const std::string& lease_id,
                       const std::string& reason, bool hand_back) {
  LeaseRef ref;
  if (!ParseLease(lease_id, &ref)) throw FarmError(Code::kInvalidArgument, "malformed lease id");
  std::lock_guard lock(mu_);
  CheckLeaseLocked(worker_id, lease_id, ref);
  SeenLocked(worker_id);
  if (workers_[worker_id].lease == lease_id) workers_[worker_id].lease.clear();
  Job* job = nullptr;
  Task* task = FindTaskLocked(ref, &job);
  if (!task || task->state != TaskStateCode::kLeased || task->worker != worker_id) return;
  if (hand_back) {
    task->state = TaskStateCode::kPending;
    job->next_pending = std::min<size_t>(job->next_pending, ref.task);
    try {
      if (task->attempt_row) store_->EndAttempt(task->attempt_row, "handed back: " + reason);
    } catch (const StorageFull& e) {
      storage_.NoteFull(e.what());  // the attempt's row stays open; the task is pending all the same
    }
    return;
  }
  RecordFailureLocked(*job, ref.task, worker_id, reason);
}

void Coordinator::RecordFailureLocked(Job& job, uint32_t task_id, const std::string& worker,
                                      const std::string& reason) {
  Task& task = job.tasks[task_id];
  ++counters_.failed;
  if (auto w = workers_.find(worker); w != workers_.end()) ++w->second.tasks_failed;
  ++task.failures;
  task.last_error = reason;
  if (std::find(task.failed_on.begin(), task.failed_on.end(), worker) == task.failed_on.end())
    task.failed_on.push_back(worker);
  job.last_failure = reason;
  task.state = TaskStateCode::kPending;
  job.next_pending = std::min<size_t>(job.next_pending, task_id);
  try {
    if (task.attempt_row) store_->EndAttempt(task.attempt_row, "failed: " + reason);
    store_->UpdateTask(job.id, TaskRecord{job.stage, int(task_id), int(task.state), task.attempts,
                                          task.failures, task.result_sha, task.last_error});
  } catch (const StorageFull& e) {
    storage_.NoteFull(e.what());  // the failure counts in memory; a restart forgets it, which is safe
  }
  if (++job.worker_failures[worker] == options_.max_attempts)
    spdlog::warn("job {}: worker {} failed {} tasks and is kept off this job", job.id, worker,
                 options_.max_attempts);
  spdlog::warn("job {}: task {} of stage {} failed on {}: {}", job.id, task_id, job.stage, worker, reason);
  if (task.failures >= options_.max_attempts)
    FailJobLocked(job, "task " + std::to_string(task_id) + " of stage " + std::to_string(job.stage) +
                           " (" + job.stage_name + ") failed " + std::to_string(task.failures) +
                           " times; last error: " + reason);
}

void Coordinator::ExpireLocked(Job& job, uint32_t task_id) {
  Task& task = job.tasks[task_id];
  ++counters_.expired;
  ++task.expiries;
  const std::string reason = "lease expired: worker " + task.worker + " sent no heartbeat for " +
                             std::to_string(options_.lease_timeout_s) + " s";
  task.last_error = reason;
  task.state = TaskStateCode::kPending;
  job.next_pending = std::min<size_t>(job.next_pending, task_id);
  try {
    if (task.attempt_row) store_->EndAttempt(task.attempt_row, "expired");
  } catch (const StorageFull& e) {
    storage_.NoteFull(e.what());
  }
  spdlog::warn("job {}: task {} of stage {}: {}", job.id, task_id, job.stage, reason);
  if (task.expiries >= 3 * options_.max_attempts)
    FailJobLocked(job, "task " + std::to_string(task_id) + " of stage " + std::to_string(job.stage) + " (" +
                           job.stage_name + ") lost " + std::to_string(task.expiries) +
                           " leases without a result (does it crash the worker that runs it?); last: " + reason);
}

bool Coordinator::OtherWorkerMayRunLocked(const Job& job, const std::string& worker_id) const {
  const auto now = Clock::now();
  const auto alive = std::chrono::milliseconds(2 * lease_timeout_ms());
  for (const auto& [id, w] : workers_) {
    if (id == worker_id || !w.seen || now - w.last_seen > alive || !w.blocklisted.empty()) continue;
    const auto f = job.worker_failures.find(id);
    if (f == job.worker_failures.end() || f->second < options_.max_attempts) return true;
  }
  return false;
}

std::string Coordinator::WaitingReasonLocked(const Job& job) const {
  if (job.state != JobState::kRunning || job.advancing) return "";
  bool pending = false;
  for (size_t t = job.next_pending; t < job.tasks.size() && !pending; ++t)
    pending = job.tasks[t].state == TaskStateCode::kPending;
  if (!pending) return "";
  const auto now = Clock::now();
  const auto alive = std::chrono::milliseconds(2 * lease_timeout_ms());
  size_t live = 0;
  std::vector<std::string> usable;  // live, trusted and not kept off this job
  for (const auto& [id, w] : workers_) {
    if (!w.seen || now - w.last_seen > alive) continue;
    ++live;
    const auto f = job.worker_failures.find(id);
    if (w.blocklisted.empty() && (f == job.worker_failures.end() || f->second < options_.max_attempts))
      usable.push_back(id);
  }
  if (live == 0) return "no live worker is connected";
  if (usable.empty())
    return "every live worker (" + std::to_string(live) + ") is blocklisted or failed " +
           std::to_string(options_.max_attempts) + " tasks of this job and is kept off it; last error: " +
           (job.last_failure.empty() ? "none" : job.last_failure);
  // A task being verified waits for a worker that has not given its own result yet.
  for (size_t t = job.next_pending; t < job.tasks.size(); ++t) {
    const Task& task = job.tasks[t];
    if (task.state != TaskStateCode::kPending) continue;
    for (const std::string& w : usable)
      if (std::none_of(task.candidates.begin(), task.candidates.end(), [&](const auto& c) { return c.first == w; }))
        return "";
  }
  return "the tasks left are being verified and wait for another live worker (results are compared between "
         "workers; " + std::to_string(usable.size()) + " may run them and each gave its own)";
}

void Coordinator::FailJobLocked(Job& job, const std::string& error) {
  job.state = JobState::kFailed;
  job.ended = Clock::now();
  job.ended_unix = UnixNow();
  job.error = error;
  job.plan.reset();
  try {
    store_->SetJobState(job.id, job.state, error);
  } catch (const StorageFull& e) {
    storage_.NoteFull(e.what());  // unrecorded: a restarted coordinator plans the job again
  }
  spdlog::warn("job {}: failed: {}", job.id, error);
  MaybeStartPlanningLocked();
}

// --- repair ---------------------------------------------------------------------------------------

void Coordinator::OnBlobCorrupted(const std::string& sha) {
  std::lock_guard lock(mu_);
  for (auto& [id, job] : jobs_) {
    // A finished job's image is made again from its stored tasks before anyone asks for it.
    if (job.state == JobState::kDone && job.result_sha == sha && !job.passes.progressive()) {
      job.result_sha.clear();
      job.state = JobState::kRunning;
      RepairLocked(job, sha, "its result image is corrupted on the coordinator's disk (quarantined)");
      continue;
    }
    if (job.state != JobState::kRunning) continue;  // planning Puts what it needs again
    bool needed = sha == job.lights_sha || sha == job.receivers_sha || sha == job.artifact_sha;
    for (const SceneFileRef& f : job.manifest.files) needed |= f.sha256 == sha;
    if (needed) RepairLocked(job, sha, "blob " + sha + " is corrupted on the coordinator's disk (quarantined)");
  }
}

void Coordinator::RepairLocked(Job& job, const std::string& sha, const std::string& what) {
  for (const SceneFileRef& f : job.manifest.files)
    if (f.sha256 == sha) {
      // The user's upload is the only copy: quarantined, it is missing, so a new submit of the
      // same scene uploads it again.
      FailJobLocked(job, "scene file \"" + f.path + "\" is corrupted on the coordinator's disk (blob " + sha +
                             ", quarantined); submit the job again to upload it again");
      return;
    }
  // The earliest stage whose work makes the blob: a task result of stage s, or the artifact
  // that combining stage s made (the input of stage s + 1). Light sets and receivers are made
  // by planning the current stage.
  int stage = job.stage;
  try {
    for (const auto& [s, artifact] : store_->Artifacts(job.id))
      if (artifact == sha) stage = std::min(stage, s);
    for (const TaskRecord& r : store_->LoadAllTasks(job.id))
      if (r.result_sha == sha) stage = std::min(stage, r.stage);
  } catch (const StorageFull& e) {
    storage_.NoteFull(e.what());
  }
  if (++job.repairs > 3 * options_.max_attempts) {
    FailJobLocked(job, "its blobs were found corrupted " + std::to_string(job.repairs) +
                           " times (the coordinator's disk is failing?); last: " + what);
    return;
  }
  RecomputeFromLocked(job, stage, what);
}

void Coordinator::RecomputeFromLocked(Job& job, int stage, const std::string& why) {
  ++counters_.repairs;
  spdlog::warn("job {}: {}; recomputing it from stage {}", job.id, why, stage);
  try {
    store_->SetJobStage(job.id, stage);
    store_->SetJobState(job.id, JobState::kPlanning, "");
  } catch (const StorageFull& e) {
    storage_.NoteFull(e.what());
  }
  job.state = JobState::kPlanning;
  job.stage = stage;
  job.tasks.clear();
  job.next_pending = 0;
  job.tasks_done = job.done_at_stage_start = 0;
  job.plan.reset();
  job.preview.reset();
  job.advancing = job.advance_paused = false;
  const int64_t id = job.id;
  planner_->Submit([this, id] { PlanJob(id); });
}

// --- verification ---------------------------------------------------------------------------------

namespace {

// A uniform number in [0, 1) from a task's identity: the same tasks are verified on every run.
double TaskHash01(int64_t job, int pass, int stage, size_t task) {
  uint64_t x = uint64_t(job) * 0x9E3779B97F4A7C15ull ^ uint64_t(pass) << 40 ^ uint64_t(stage) << 32 ^ uint64_t(task);
  x ^= x >> 30;
  x *= 0xBF58476D1CE4E5B9ull;
  x ^= x >> 27;
  x *= 0x94D049BB133111EBull;
  x ^= x >> 31;
  return double(x >> 11) * 0x1.0p-53;
}

}  // namespace

void Coordinator::MarkVerifiedTasksLocked(Job& job) const {
  for (size_t t = 0; t < job.tasks.size(); ++t)
    job.tasks[t].verify = job.settings.verify ||
                          (options_.verify_share > 0 && TaskHash01(job.id, job.pass, job.stage, t) < options_.verify_share);
}

void Coordinator::BlocklistLocked(const std::string& liar, const std::string& reason) {
  WorkerInfo& w = workers_[liar];
  if (!w.blocklisted.empty()) return;
  w.blocklisted = reason;
  spdlog::error("worker {} ({}) is blocklisted: {}; its results for unfinished jobs are computed again", liar,
                w.name, reason);
  try {
    store_->SetWorkerBlocklisted(liar, reason);
  } catch (const StorageFull& e) {
    storage_.NoteFull(e.what());
  }
  for (auto& [id, job] : jobs_) {
    if (IsTerminal(job.state)) continue;
    try {
      // Every result it gave this job that the job kept (stored: earlier stages; in memory: the
      // current one), except those another worker confirmed.
      std::set<std::pair<int, int>> mine;
      for (const auto& st : store_->TasksDoneBy(job.id, liar)) mine.insert(st);
      if (job.state == JobState::kRunning)
        for (size_t t = 0; t < job.tasks.size(); ++t) {
          const Task& task = job.tasks[t];
          if (task.worker == liar && task.state == TaskStateCode::kDone) mine.insert({job.stage, int(t)});
          if (task.verified) mine.erase({job.stage, int(t)});
        }
      if (mine.empty()) continue;
      int earliest = job.stage;
      for (const TaskRecord& r : store_->LoadAllTasks(job.id)) {
        if (!mine.count({r.stage, r.task_id}) || r.state != int(TaskStateCode::kDone)) continue;
        TaskRecord reset = r;
        reset.state = int(TaskStateCode::kPending);
        reset.result_sha.clear();
        reset.last_error = "result discarded: worker " + liar + " is blocklisted";
        store_->UpdateTask(job.id, reset);
        earliest = std::min(earliest, r.stage);
      }
      if (earliest < job.stage || job.state != JobState::kRunning || job.advancing) {
        RecomputeFromLocked(job, earliest, "worker " + liar + " is blocklisted");
        continue;
      }
      for (const auto& [stage, t] : mine) {
        if (stage != job.stage || size_t(t) >= job.tasks.size()) continue;
        Task& task = job.tasks[size_t(t)];
        if (task.state != TaskStateCode::kDone) continue;
        task.state = TaskStateCode::kPending;
        task.result_sha.clear();
        task.worker.clear();
        --job.tasks_done;
        job.next_pending = std::min<size_t>(job.next_pending, size_t(t));
      }
    } catch (const StorageFull& e) {
      storage_.NoteFull(e.what());
    }
  }
}

// --- planning and stages --------------------------------------------------------------------------

void Coordinator::MaybeStartPlanningLocked() {
  if (stopping_ || storage_.full()) return;
  int active = 0;
  for (const auto& [id, j] : jobs_)
    active += j.state == JobState::kPlanning || j.state == JobState::kRunning;
  while (active < options_.max_active_jobs) {
    Job* next = nullptr;
    for (auto& [id, j] : jobs_)
      if (j.state == JobState::kQueued && (!next || j.priority > next->priority)) next = &j;
    if (!next) return;
    try {
      store_->SetJobState(next->id, JobState::kPlanning, "");
    } catch (const StorageFull& e) {
      storage_.NoteFull(e.what());
      return;
    }
    next->state = JobState::kPlanning;
    next->started = next->pass_started = Clock::now();
    const int64_t id = next->id;
    planner_->Submit([this, id] { PlanJob(id); });
    ++active;
  }
}

void Coordinator::PlanJob(int64_t id) {
  SceneManifest manifest;
  RenderSettings settings;
  int stage = 0;
  {
    std::lock_guard lock(mu_);
    auto found = jobs_.find(id);
    if (found == jobs_.end()) return;  // deleted meanwhile
    Job& job = found->second;
    if (job.state != JobState::kPlanning) return;  // cancelled meanwhile
    manifest = job.manifest;
    settings = PassSettings(job);
    stage = job.stage;
  }
  PlannedStage planned;
  try {
    planned = job_planner_->PlanStage(id, manifest, settings, stage);
  } catch (const BlobCorrupted& e) {
    std::lock_guard lock(mu_);
    auto found = jobs_.find(id);
    if (found == jobs_.end()) return;  // deleted meanwhile
    Job& job = found->second;
    if (job.state == JobState::kPlanning) RepairLocked(job, e.sha256(), e.what());
    return;
  } catch (const std::exception& e) {
    const bool storage = storage_.IsFault(e);
    if (storage) storage_.NoteFull(e.what());
    std::lock_guard lock(mu_);
    auto found = jobs_.find(id);
    if (found == jobs_.end()) return;  // deleted meanwhile
    Job& job = found->second;
    if (job.state != JobState::kPlanning) return;
    if (storage) {
      job.state = JobState::kQueued;  // planned again when space returns
      spdlog::warn("job {}: planning paused, the disk is full: {}", id, e.what());
      return;
    }
    FailJobLocked(job, e.what());
    return;
  }
  std::vector<Task> tasks = MakeTasks(planned.specs);
  ApplyRecords(tasks, planned.records);
  const uint64_t attempts = [&] {
    uint64_t n = 0;
    for (const TaskRecord& r : store_->LoadAllTasks(id)) n += uint64_t(r.attempts);
    return n;
  }();

  std::lock_guard lock(mu_);
  auto found = jobs_.find(id);
  if (found == jobs_.end()) return;  // deleted meanwhile
  Job& job = found->second;
  if (job.state != JobState::kPlanning) return;
  const StageEngine engine(*planned.plan);
  job.plan = planned.plan;
  job.times = planned.times;
  job.lights_sha = planned.lights_sha;
  job.receivers_sha = planned.receivers_sha;
  job.artifact_sha = planned.artifact_sha;
  job.clamp = planned.plan->matrix_options.clamp;
  job.stage_count = engine.stage_count();
  job.stage_name = engine.stage_name(stage);
  job.stage_high = std::max(job.stage_high, stage);
  job.tasks = std::move(tasks);
  MarkVerifiedTasksLocked(job);
  job.next_pending = 0;
  job.tasks_done = 0;
  for (const Task& t : job.tasks) job.tasks_done += t.state == TaskStateCode::kDone;
  job.done_at_stage_start = job.tasks_done;
  job.stage_started = Clock::now();
  job.attempts_total += attempts;
  job.state = JobState::kRunning;
  try {
    store_->SetJobState(id, job.state, "");
  } catch (const StorageFull& e) {
    storage_.NoteFull(e.what());  // the store says PLANNING: a restart plans it again, which is safe
  }
  spdlog::info("job {}: stage {} ({}) has {} tasks, {} done", id, stage, job.stage_name,
               job.tasks.size(), job.tasks_done);
  if (job.tasks_done == job.tasks.size()) {
    job.advancing = true;
    planner_->Submit([this, id] { AdvanceStage(id); });
  }
}

void Coordinator::ApplyRecords(std::vector<Task>& tasks, const std::vector<TaskRecord>& records) const {
  for (const TaskRecord& r : records) {
    if (r.task_id < 0 || size_t(r.task_id) >= tasks.size()) continue;
    Task& t = tasks[size_t(r.task_id)];
    t.attempts = r.attempts;
    t.failures = r.failures;
    t.last_error = r.last_error;
    // A result quarantined since is missing: the task runs again.
    if (r.state == int(TaskStateCode::kDone) && blobs_->Has(r.result_sha)) {
      t.state = TaskStateCode::kDone;
      t.result_sha = r.result_sha;
    }
  }
}

std::vector<Coordinator::Task> Coordinator::MakeTasks(const std::vector<SubMatrixTask>& specs) {
  std::vector<Task> tasks;
  tasks.reserve(specs.size());
  for (const SubMatrixTask& s : specs) {
    Task t;
    t.spec = SerializeTask(s);
    t.rows = s.rows.size();
    tasks.push_back(std::move(t));
  }
  return tasks;
}

void Coordinator::AdvanceStage(int64_t id) {
  std::shared_ptr<Plan> plan;
  int stage = 0;
  std::vector<std::string> results;
  {
    std::lock_guard lock(mu_);
    auto found = jobs_.find(id);
    if (found == jobs_.end()) return;  // deleted meanwhile
    Job& job = found->second;
    if (job.state != JobState::kRunning || !job.plan) return;
    plan = job.plan;
    stage = job.stage;
    for (const Task& t : job.tasks) results.push_back(t.result_sha);
    job.times.Add(job.stage_name, Seconds(Clock::now() - job.stage_started));
  }
  const StageEngine engine(*plan);
  try {
    if (engine.is_final(stage)) {
      FinishJob(id, plan, stage);
      return;
    }
    NextStage next = job_planner_->CombineStage(id, *plan, stage, results);
    std::lock_guard lock(mu_);
    auto found = jobs_.find(id);
    if (found == jobs_.end()) return;  // deleted meanwhile
    Job& job = found->second;
    if (job.state != JobState::kRunning) return;
    job.stage = stage + 1;
    job.stage_high = std::max(job.stage_high, job.stage);
    job.stage_name = engine.stage_name(job.stage);
    job.artifact_sha = next.artifact_sha;
    job.tasks = MakeTasks(next.specs);
    ApplyRecords(job.tasks, next.records);
    MarkVerifiedTasksLocked(job);
    job.next_pending = 0;
    job.tasks_done = 0;
    for (const Task& t : job.tasks) job.tasks_done += t.state == TaskStateCode::kDone;
    job.done_at_stage_start = job.tasks_done;
    job.stage_started = Clock::now();
    job.advancing = false;
    if (job.tasks_done == job.tasks.size()) {
      job.advancing = true;
      planner_->Submit([this, id] { AdvanceStage(id); });
    }
  } catch (const BlobCorrupted& e) {
    std::lock_guard lock(mu_);
    auto found = jobs_.find(id);
    if (found == jobs_.end()) return;  // deleted meanwhile
    Job& job = found->second;
    if (!IsTerminal(job.state)) RepairLocked(job, e.sha256(), e.what());
  } catch (const std::exception& e) {
    const bool storage = storage_.IsFault(e);
    if (storage) storage_.NoteFull(e.what());
    std::lock_guard lock(mu_);
    auto found = jobs_.find(id);
    if (found == jobs_.end()) return;  // deleted meanwhile
    Job& job = found->second;
    if (IsTerminal(job.state)) return;
    if (storage) {
      // The stage's results are all stored: it is combined (or the film made) when space returns.
      job.advancing = false;
      job.advance_paused = true;
      spdlog::warn("job {}: stage {} waits for disk space: {}", id, stage, e.what());
      return;
    }
    FailJobLocked(job, std::string("stage ") + std::to_string(stage) + ": " + e.what());
  }
}

RenderSettings Coordinator::PassSettings(const Job& job) {
  RenderSettings settings = job.settings;
  settings.seed = PassSeed(job.settings.seed, uint32_t(job.pass));
  return settings;
}

void Coordinator::FinishJob(int64_t id, std::shared_ptr<Plan> plan, int final_stage) {
  std::vector<Bytes> specs;
  PhaseTimes times;
  Clock::time_point pass_started;
  uint64_t job_seed = 0;
  RenderSettings settings;
  std::string root, previous_stats;
  int pass = 0;
  PassPlan passes;
  std::shared_ptr<const PassAccumulator> acc;
  {
    std::lock_guard lock(mu_);
    auto found = jobs_.find(id);
    if (found == jobs_.end()) return;  // deleted meanwhile
    Job& job = found->second;
    for (const Task& t : job.tasks) specs.push_back(t.spec);
    times = job.times;
    pass_started = job.pass_started;
    job_seed = job.settings.seed;
    settings = PassSettings(job);
    root = job.manifest.root;
    pass = job.pass;
    passes = job.passes;
    acc = job.acc;
    previous_stats = job.stats_json;
  }
  PassOutcome outcome = job_planner_->AssemblePass(id, *plan, settings, root, final_stage, specs, times,
                                                   Seconds(Clock::now() - pass_started));
  FinishedJob finished;
  if (!passes.progressive()) {
    finished = job_planner_->Finish(id, std::move(outcome));
  } else {
    // The accumulation is copied, so status calls read the published one meanwhile.
    auto next = std::make_shared<PassAccumulator>(acc ? *acc : PassAccumulator());
    finished = job_planner_->FinishPass(
        id, pass, passes, *next, std::move(outcome), Seconds(Clock::now() - pass_started), job_seed,
        previous_stats.empty() ? nlohmann::json::object() : nlohmann::json::parse(previous_stats));
    acc = std::move(next);
  }
  if (options_.on_result) options_.on_result(std::to_string(id), finished.image);
  std::lock_guard lock(mu_);
  auto found = jobs_.find(id);
  if (found == jobs_.end()) return;  // deleted meanwhile
  Job& job = found->second;
  job.result_sha = finished.result_sha;
  job.stats_json = finished.stats_json;
  job.plan.reset();
  job.preview.reset();
  job.advancing = false;
  if (passes.progressive()) {
    job.acc = acc;
    job.noise = finished.noise;
    ++job.pass;
    if (finished.more_passes) {
      spdlog::info("job {}: pass {} done (noise {:.4f}, p90 {:.4f})", id, pass, finished.noise.rel_stderr,
                   finished.noise.p90_rel_stderr);
      if (job.state != JobState::kRunning) return;  // cancelled meanwhile: the passes so far are its result
      // The next pass keeps the job's slot: planned at once, its tasks from stage 0.
      job.state = JobState::kPlanning;
      job.stage = 0;
      job.tasks.clear();
      job.next_pending = 0;
      job.tasks_done = job.done_at_stage_start = 0;
      job.times = PhaseTimes();
      job.pass_started = Clock::now();
      try {
        store_->SetJobState(id, job.state, "");
      } catch (const StorageFull& e) {
        storage_.NoteFull(e.what());
      }
      planner_->Submit([this, id] { PlanJob(id); });
      return;
    }
  }
  job.state = JobState::kDone;
  job.ended = Clock::now();
  job.ended_unix = UnixNow();
  spdlog::info("job {}: done ({} tasks, {} attempts)", id, finished.tasks, finished.attempts);
  MaybeStartPlanningLocked();
}

// --- deletion and storage upkeep ---------------------------------------------------------------------

void Coordinator::Delete(const std::string& job_id) {
  int64_t id = 0;
  {
    std::lock_guard lock(mu_);
    Job& job = FindJob(job_id);
    id = job.id;
    store_->DeleteJob(id);  // first: a full disk refuses the delete and changes nothing
    if (!IsTerminal(job.state)) spdlog::info("job {}: cancelled to be deleted", id);
    jobs_.erase(id);  // planning in flight finds it gone and stops; stale leases are NOT_FOUND
    ++counters_.deleted;
    spdlog::info("job {}: deleted", id);
    MaybeStartPlanningLocked();
  }
  std::error_code ec;
  fs::remove_all(options_.state_dir + "/jobs/" + std::to_string(id), ec);
  tick_cv_.notify_all();  // the upkeep thread collects its blobs (after their grace period)
}

size_t Coordinator::CollectGarbage() {
  std::lock_guard gc(gc_mu_);
  std::set<std::string> live;
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, job] : jobs_) {
      for (const SceneFileRef& f : job.manifest.files) live.insert(f.sha256);
      for (const std::string* sha : {&job.result_sha, &job.lights_sha, &job.receivers_sha, &job.artifact_sha})
        if (!sha->empty()) live.insert(*sha);
      for (const Task& t : job.tasks) {
        if (!t.result_sha.empty()) live.insert(t.result_sha);
        for (const auto& c : t.candidates) live.insert(c.second);
      }
    }
  }
  // The store's names (task results, artifacts, accumulations of every kept job) after the
  // jobs' own: a job deleted in between only leaves more to collect next time. Rows a planner
  // wrote for a job deleted while it worked go first.
  store_->DeleteOrphans();
  for (std::string& sha : store_->ReferencedBlobs()) live.insert(std::move(sha));
  const auto cutoff = fs::file_time_type::clock::now() -
                      std::chrono::duration_cast<fs::file_time_type::duration>(
                          std::chrono::duration<double>(options_.gc_grace_s));
  size_t removed = 0;
  uint64_t bytes = 0;
  for (const BlobStore::Entry& e : blobs_->List()) {
    if (live.count(e.sha256) || e.written > cutoff) continue;
    bytes += blobs_->Remove(e.sha256);
    ++removed;
  }
  counters_.gc_removed += removed;
  counters_.gc_removed_bytes += bytes;
  if (removed) spdlog::info("blob store: collected {} blobs no job uses ({} MiB)", removed, bytes >> 20);
  return removed;
}

void Coordinator::ApplyRetention() {
  if (options_.retain_finished_s <= 0) return;
  std::vector<std::string> expired;
  {
    std::lock_guard lock(mu_);
    const double now = UnixNow();
    for (const auto& [id, job] : jobs_)
      if (IsTerminal(job.state) && job.ended_unix > 0 && now - job.ended_unix > options_.retain_finished_s)
        expired.push_back(std::to_string(id));
  }
  for (const std::string& id : expired) {
    try {
      Delete(id);
      spdlog::info("job {}: deleted by the retention policy (--retain-finished-s {})", id, options_.retain_finished_s);
    } catch (const std::exception& e) {
      spdlog::warn("job {}: retention could not delete it: {}", id, e.what());
    }
  }
}

void Coordinator::ScrubStep(uint64_t bytes) {
  if (scrub_next_ >= scrub_queue_.size()) {
    if (!scrub_queue_.empty()) ++counters_.scrub_passes;
    scrub_queue_.clear();
    for (const BlobStore::Entry& e : blobs_->List()) scrub_queue_.push_back(e.sha256);
    std::sort(scrub_queue_.begin(), scrub_queue_.end());
    scrub_next_ = 0;
  }
  uint64_t done = 0;
  while (done < bytes && scrub_next_ < scrub_queue_.size()) {
    const std::string& sha = scrub_queue_[scrub_next_++];
    if (!blobs_->Has(sha)) continue;  // collected or quarantined meanwhile
    std::error_code ec;
    done += fs::file_size(blobs_->Path(sha), ec);
    const uint64_t corrupted = blobs_->corrupted();
    if (!blobs_->Verify(sha) && blobs_->corrupted() > corrupted) OnBlobCorrupted(sha);  // quarantined: made again
  }
  counters_.scrubbed_bytes += done;
}

void Coordinator::UpkeepLoop() {
  auto last_gc = Clock::now();
  std::unique_lock lock(mu_);
  while (!stopping_) {
    tick_cv_.wait_for(lock, std::chrono::seconds(1));
    if (stopping_) break;
    lock.unlock();
    try {
      if (options_.scrub_mb_per_s > 0) ScrubStep(uint64_t(options_.scrub_mb_per_s * 1024 * 1024));
      if (Seconds(Clock::now() - last_gc) >= options_.gc_interval_s) {
        last_gc = Clock::now();
        ApplyRetention();
        CollectGarbage();  // it frees space: it runs on a full disk too
      }
    } catch (const std::exception& e) {
      spdlog::error("storage upkeep: {}", e.what());
    }
    lock.lock();
  }
}

// --- storage ---------------------------------------------------------------------------------------

void Coordinator::CheckStorageLocked() {
  if (!storage_.CheckRecovered([this] { return blobs_->CanWrite(1 << 20); })) return;
  for (auto& [id, job] : jobs_) {
    if (job.state != JobState::kRunning || !job.advance_paused) continue;
    job.advance_paused = false;
    job.advancing = true;
    const int64_t job_id = id;
    planner_->Submit([this, job_id] { AdvanceStage(job_id); });
  }
  MaybeStartPlanningLocked();
}

void Coordinator::TickLoop() {
  const auto period = std::chrono::milliseconds(
      std::clamp<int64_t>(int64_t(options_.lease_timeout_s * 1000.0 / 10.0), 10, 1000));
  std::unique_lock lock(mu_);
  while (!stopping_) {
    tick_cv_.wait_for(lock, period);
    if (stopping_) break;
    CheckStorageLocked();
    // While the disk is full a worker cannot deliver: its lease is left to run on, not failed.
    if (storage_.full()) continue;
    // Expired leases: the worker died or hangs; the task goes back to the queue.
    const auto now = Clock::now();
    for (auto& [id, job] : jobs_) {
      if (job.state != JobState::kRunning) continue;
      for (size_t t = 0; t < job.tasks.size() && job.state == JobState::kRunning; ++t) {
        Task& task = job.tasks[t];
        if (task.state == TaskStateCode::kLeased && task.expiry < now) ExpireLocked(job, uint32_t(t));
      }
      // A job no live worker may run fails once that has lasted two lease timeouts (a worker
      // restarting on its cache has time to come back); until then `waiting` says why.
      const std::string reason = job.state == JobState::kRunning ? WaitingReasonLocked(job) : "";
      if (reason.rfind("every live worker", 0) != 0) {
        job.blocked_since = {};
      } else if (job.blocked_since == Clock::time_point{}) {
        job.blocked_since = now;
      } else if (now - job.blocked_since > std::chrono::milliseconds(2 * lease_timeout_ms())) {
        FailJobLocked(job, reason);
      }
    }
  }
}

std::string Coordinator::MetricsText() {
  FarmGauges gauges;
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, job] : jobs_) {
      ++gauges.jobs_by_state[JobStateName(job.state)];
      if (job.state != JobState::kRunning) continue;
      for (const Task& t : job.tasks) {
        gauges.tasks_pending += t.state == TaskStateCode::kPending;
        gauges.tasks_leased += t.state == TaskStateCode::kLeased;
      }
    }
    gauges.workers = workers_.size();
  }
  gauges.storage_full = storage_.full();
  gauges.blobs_corrupted = blobs_->corrupted();
  return PrometheusText(counters_, gauges);
}

}  // namespace lightfarm
