#include "worker/worker.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <future>
#include <random>
#include <thread>

#include <tbb/task_group.h>

#include "common/farm/content_hash.h"
#include "common/farm/farm_protocol.h"
#include "common/farm/proto_convert.h"
#include "common/farm/rpc.h"
#include "common/render/serialize.h"
#include "common/util/file.h"
#include "common/scene/scene_cache.h"

namespace lightfarm {

namespace fs = std::filesystem;

namespace {

Bytes ReadBytes(const std::string& path) {
  const std::string data = ReadFile(path);
  return Bytes(data.begin(), data.end());
}

bool Transient(grpc::StatusCode c) {
  return c == grpc::StatusCode::UNAVAILABLE || c == grpc::StatusCode::DEADLINE_EXCEEDED ||
         c == grpc::StatusCode::CANCELLED || c == grpc::StatusCode::INTERNAL ||
         c == grpc::StatusCode::UNKNOWN;
}

}  // namespace

// --- BlobCache ----------------------------------------------------------------------------------

BlobCache::BlobCache(std::string dir, uint64_t max_bytes) : dir_(std::move(dir)), max_bytes_(max_bytes) {
  fs::create_directories(dir_ + "/tmp");
  std::error_code ec;
  // What a killed worker left half-written: partial blobs and scene directories, all of it (a
  // scene directory left behind made every later worker on this cache fail its tasks).
  for (const auto& e : fs::directory_iterator(dir_ + "/tmp", ec)) fs::remove_all(e.path(), ec);
  // Blobs of a previous run are reused, oldest first out.
  std::vector<std::pair<fs::file_time_type, fs::path>> existing;
  for (const auto& e : fs::directory_iterator(dir_))
    if (e.is_regular_file() && IsSha256Hex(e.path().filename().string()))
      existing.emplace_back(e.last_write_time(), e.path());
  std::sort(existing.begin(), existing.end());
  for (const auto& [t, p] : existing) Touch(p.filename().string(), fs::file_size(p));
}

bool BlobCache::Has(const std::string& sha) {
  std::lock_guard lock(mu_);
  auto it = entries_.find(sha);
  if (it == entries_.end()) return false;
  lru_.splice(lru_.begin(), lru_, it->second.second);
  return true;
}

std::string BlobCache::TempPath() {
  std::lock_guard lock(mu_);
  return dir_ + "/tmp/" + std::to_string(counter_++);
}

void BlobCache::Touch(const std::string& sha, uint64_t size) {
  auto it = entries_.find(sha);
  if (it != entries_.end()) {
    lru_.splice(lru_.begin(), lru_, it->second.second);
    return;
  }
  lru_.push_front(sha);
  entries_[sha] = {size, lru_.begin()};
  total_ += size;
  // Evict least recently used blobs, keeping at least the newest.
  while (total_ > max_bytes_ && lru_.size() > 1) {
    const std::string victim = lru_.back();
    lru_.pop_back();
    total_ -= entries_[victim].first;
    entries_.erase(victim);
    std::error_code ec;
    fs::remove(Path(victim), ec);
  }
}

void BlobCache::Adopt(const std::string& sha, const std::string& tmp_path) {
  const uint64_t size = fs::file_size(tmp_path);
  fs::rename(tmp_path, Path(sha));
  std::lock_guard lock(mu_);
  Touch(sha, size);
}

void BlobCache::Forget(const std::string& sha) {
  std::lock_guard lock(mu_);
  auto it = entries_.find(sha);
  if (it != entries_.end()) {
    total_ -= it->second.first;
    lru_.erase(it->second.second);
    entries_.erase(it);
  }
  std::error_code ec;
  fs::remove(Path(sha), ec);
}

// --- Worker -------------------------------------------------------------------------------------

// What a job's tasks need: its plan, rebuilt from the coordinator's blobs (RebuildPlan).
struct Worker::JobRuntime {
  std::string key;
  Plan plan;
};

Worker::Worker(std::shared_ptr<grpc::Channel> channel, WorkerOptions options)
    : stub_(v1::WorkerService::NewStub(channel)), options_(std::move(options)) {
  if (options_.name.empty()) {
    char host[256] = {};
    gethostname(host, sizeof(host) - 1);
    options_.name = std::string(host) + "-" + std::to_string(getpid());
  }
  std::string dir = options_.cache_dir;
  if (dir.empty()) {
    std::random_device rd;
    temp_dir_ = (fs::temp_directory_path() / ("lightfarm-worker-" + std::to_string(getpid()) + "-" +
                                              std::to_string(rd()))).string();
    dir = temp_dir_;
  }
  cache_ = std::make_unique<BlobCache>(dir + "/blobs", options_.cache_bytes);
}

Worker::~Worker() {
  runtime_.reset();
  if (!temp_dir_.empty()) {
    std::error_code ec;
    fs::remove_all(temp_dir_, ec);
  }
}

void Worker::Prepare(grpc::ClientContext* ctx, double timeout_s) const {
  PrepareCall(ctx, options_.token, timeout_s);
}

void Worker::Stop(bool hand_back) {
  hand_back_ = hand_back_ || hand_back;
  stop_ = true;
  sleep_cv_.notify_all();
}

void Worker::SleepUnlessStopping(double seconds) {
  std::unique_lock lock(sleep_mu_);
  sleep_cv_.wait_for(lock, std::chrono::milliseconds(int64_t(seconds * 1000.0)), [&] { return stop_.load(); });
}

void Worker::Register() {
  double backoff = 0.1;
  while (!stop_) {
    v1::RegisterRequest req;
    req.set_name(options_.name);
    req.set_protocol_version(options_.protocol_version);
    req.set_software_version(options_.software_version);
    // 0 (all cores) is reported as the count it means.
    req.set_threads(options_.threads > 0 ? options_.threads : int(std::thread::hardware_concurrency()));
    v1::RegisterResponse resp;
    grpc::ClientContext ctx;
    Prepare(&ctx, options_.rpc_timeout_s);
    grpc::Status st = stub_->Register(&ctx, req, &resp);
    if (st.ok()) {
      worker_id_ = resp.worker_id();
      lease_timeout_ms_ = std::max(100u, resp.lease_timeout_ms());
      spdlog::info("registered as {} (lease timeout {} ms)", worker_id_, lease_timeout_ms_);
      return;
    }
    if (st.error_code() == grpc::StatusCode::FAILED_PRECONDITION ||
        st.error_code() == grpc::StatusCode::UNAUTHENTICATED ||
        st.error_code() == grpc::StatusCode::PERMISSION_DENIED)
      throw WorkerRefused("coordinator refused this worker: " + std::string(RpcError(st).what()));
    spdlog::warn("coordinator unreachable ({}); retrying in {:.1f}s", st.error_message(), backoff);
    SleepUnlessStopping(backoff);
    backoff = std::min(backoff * 2, 5.0);
  }
}

void Worker::Run() {
  Register();
  double backoff = options_.idle_poll_s;
  while (!stop_) {
    try {
      if (RunOneTask()) {
        backoff = options_.idle_poll_s;
        continue;
      }
      SleepUnlessStopping(options_.idle_poll_s);
    } catch (const RpcError& e) {
      if (e.code() == grpc::StatusCode::NOT_FOUND) {
        // The coordinator no longer knows this worker (its state was reset): register again.
        Register();
        continue;
      }
      if (e.code() == grpc::StatusCode::UNAUTHENTICATED) throw WorkerRefused(e.what());
      spdlog::warn("coordinator: {}; retrying in {:.1f}s", e.what(), backoff);
      SleepUnlessStopping(backoff);
      backoff = std::min(backoff * 2, 5.0);
    }
  }
  // Stopped with a task leased alongside the last completion: hand it back now rather than
  // leave it to expire.
  if (next_lease_) {
    ReportFailure(next_lease_->lease_id(), "worker stopping", true);
    next_lease_.reset();
  }
}

std::string Worker::FetchBlob(const std::string& sha) {
  if (cache_->Has(sha)) {
    // The cache is a directory anyone (a disk, a person) can change between tasks: a blob is
    // used only while its bytes still hash to its name, else it is fetched again.
    std::string got;
    try {
      got = Sha256OfFile(cache_->Path(sha));
    } catch (const std::exception&) {
    }
    if (got == sha) return cache_->Path(sha);
    spdlog::warn("cached blob {} is corrupted (its bytes hash to {}); fetching it again", sha,
                 got.empty() ? "nothing: unreadable" : got);
    ++cache_corrupted_;
    cache_->Forget(sha);
  }
  const std::string tmp = cache_->TempPath();
  {
    std::ofstream out(tmp, std::ios::binary);
    v1::FetchBlobRequest req;
    req.set_sha256(sha);
    grpc::ClientContext ctx;
    Prepare(&ctx, options_.rpc_timeout_s * 20);
    auto reader = stub_->FetchBlob(&ctx, req);
    v1::BlobChunk chunk;
    Sha256 hash;
    while (reader->Read(&chunk)) {
      hash.Update(chunk.data().data(), chunk.data().size());
      out.write(chunk.data().data(), std::streamsize(chunk.data().size()));
    }
    ThrowIfError(reader->Finish());
    out.close();
    if (!out) throw std::runtime_error("cannot write " + tmp);
    const std::string got = hash.HexDigest();
    if (got != sha) throw std::runtime_error("blob " + sha + " arrived corrupted (hash " + got + ")");
  }
  cache_->Adopt(sha, tmp);
  return cache_->Path(sha);
}

std::shared_ptr<Worker::JobRuntime> Worker::Runtime(const v1::JobContext& job) {
  const std::string key = job.job_id() + "/" + job.lights_sha256() + "/" + job.receivers_sha256();
  if (runtime_ && runtime_->key == key) return runtime_;
  runtime_.reset();  // one job's matrix at a time
  auto rt = std::make_shared<JobRuntime>();
  rt->key = key;
  // Materialize the scene files in their relative layout, then build as the coordinator did.
  const fs::path dir = fs::path(cache_->TempPath() + "-scene");
  ScopedRemoveDir cleanup(dir);
  for (const v1::SceneFile& f : job.scene().files()) {
    const fs::path rel(f.path());
    if (!IsSafeScenePath(f.path())) throw std::runtime_error("unsafe scene path " + f.path());
    fs::create_directories((dir / rel).parent_path());
    fs::copy_file(FetchBlob(f.sha256()), dir / rel);
  }
  const RenderSettings settings = FromProto(job.settings());
  // Parsed once per job in this process (a later pass, or the coordinator or client of an
  // embedded render, finds it in the cache).
  const std::shared_ptr<const SceneDescription> desc =
      SceneCache::Process().Get(FromProto(job.scene()).ContentKey(), dir.string(), job.scene().root());
  rt->plan = RebuildPlan(*desc, settings, job.clamp(),
                         DeserializeLightSet(ReadBytes(FetchBlob(job.lights_sha256()))),
                         DeserializeReceiverSet(ReadBytes(FetchBlob(job.receivers_sha256()))));
  runtime_ = rt;
  return rt;
}

struct Worker::LeasedTask {
  std::shared_ptr<JobRuntime> rt;
  SubMatrixTask task;
  StageArtifact artifact;
};

bool Worker::RunOneTask() {
  v1::LeaseTaskRequest req;
  req.set_worker_id(worker_id_);
  v1::LeaseTaskResponse lease;
  if (next_lease_) {  // leased with the previous task's completion
    lease = std::move(*next_lease_);
    next_lease_.reset();
  } else {
    grpc::ClientContext ctx;
    Prepare(&ctx, options_.rpc_timeout_s);
    ThrowIfError(stub_->LeaseTask(&ctx, req, &lease));
  }
  if (!lease.has_task()) return false;
  if (lease.lease_timeout_ms() > 0) lease_timeout_ms_ = lease.lease_timeout_ms();
  spdlog::debug("leased {} (job {})", lease.lease_id(), lease.job().job_id());

  LeasedTask leased;
  try {
    leased = PrepareTask(lease);
  } catch (const RpcError& e) {
    if (Transient(e.code())) throw;  // the coordinator is away: Run retries, the lease expires
    // A blob corrupted on the coordinator's disk is not this worker's failure: the task goes
    // back while the coordinator makes the blob again.
    const bool theirs = e.code() == grpc::StatusCode::DATA_LOSS;
    ReportFailure(lease.lease_id(), std::string("cannot prepare the task: ") + e.what(), theirs);
    return true;
  } catch (const std::exception& e) {
    ReportFailure(lease.lease_id(), std::string("cannot prepare the task: ") + e.what(), false);
    return true;
  }
  TaskOutput output;
  try {
    switch (RunUnderLease(leased, lease.lease_id(), &output)) {
      case Ending::kDone: break;
      case Ending::kHandedBack: ReportFailure(lease.lease_id(), "worker shutting down", true); return true;
      case Ending::kLeaseLost:
        spdlog::info("lease {} is no longer ours (job cancelled or task re-leased); task stopped",
                     lease.lease_id());
        ++tasks_cancelled_;
        return true;
    }
  } catch (const std::exception& e) {
    ReportFailure(lease.lease_id(), std::string("task failed: ") + e.what(), false);
    return true;
  }
  DeliverResult(lease.lease_id(), output);
  return true;
}

Worker::LeasedTask Worker::PrepareTask(const v1::LeaseTaskResponse& lease) {
  LeasedTask leased;
  leased.rt = Runtime(lease.job());
  leased.task = DeserializeTask(ByteView(reinterpret_cast<const uint8_t*>(lease.task().data()), lease.task().size()));
  // Matrix methods' rows index the lighting matrix, film methods' the pixels.
  const size_t row_limit = FinalRows(leased.rt->plan);
  for (uint32_t r : leased.task.rows)
    if (r >= row_limit) throw std::runtime_error("task row " + std::to_string(r) + " out of range");
  if (!lease.artifact_sha256().empty()) leased.artifact = ReadBytes(FetchBlob(lease.artifact_sha256()));
  return leased;
}

Worker::Ending Worker::RunUnderLease(const LeasedTask& leased, const std::string& lease_id, TaskOutput* output) {
  // The task runs inside a task_group: the oneTBB loops it starts bind to the group's context, so
  // cancelling the group (job cancelled, lease lost, shutdown) stops them at their next chunk and
  // the worker is free again in a fraction of the task's time. A cancelled result is dropped.
  const Plan& plan = leased.rt->plan;
  tbb::task_group group;
  auto future = std::async(std::launch::async, [&] {
    TaskOutput out;
    group.run_and_wait([&] { out = RunGatherTask(*plan.method, plan.context(), leased.task, leased.artifact); });
    return out;
  });
  const auto beat = std::chrono::milliseconds(std::max<uint32_t>(20, lease_timeout_ms_ / 4));
  bool keep = true;
  while (future.wait_for(beat) != std::future_status::ready) {
    if (hand_back_) break;
    v1::HeartbeatRequest hb;
    hb.set_worker_id(worker_id_);
    hb.set_lease_id(lease_id);
    v1::HeartbeatResponse resp;
    grpc::ClientContext ctx;
    Prepare(&ctx, std::min(options_.rpc_timeout_s, lease_timeout_ms_ / 2000.0));
    grpc::Status st = stub_->Heartbeat(&ctx, hb, &resp);
    if (st.ok() && !resp.keep_going()) {  // cancelled or re-leased: the result is unwanted
      keep = false;
      break;
    }
  }
  if (hand_back_ || !keep) {
    group.cancel();
    try {
      future.get();
    } catch (const std::exception&) {
      // a cancelled task may fail on its partial data; nothing of it is kept
    }
    return hand_back_ ? Ending::kHandedBack : Ending::kLeaseLost;
  }
  *output = future.get();  // rethrows what the task threw
  return Ending::kDone;
}

void Worker::DeliverResult(const std::string& lease_id, const TaskOutput& output) {
  // Retried while the coordinator is away: it accepts a completion for a task it still needs,
  // even after a restart.
  const Bytes bytes = SerializeTaskOutput(output);
  double backoff = 0.1;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  for (;;) {
    grpc::ClientContext ctx;
    Prepare(&ctx, options_.rpc_timeout_s + double(bytes.size()) / 1e6);
    v1::CompleteTaskResponse resp;
    auto writer = stub_->CompleteTask(&ctx, &resp);
    const grpc::Status st = WriteChunked(*writer, bytes.data(), bytes.size(), [&](v1::TaskResultChunk& chunk) {
      chunk.set_worker_id(worker_id_);
      chunk.set_lease_id(lease_id);
      chunk.set_total_size(bytes.size());
      chunk.set_lease_next(!stop_ && !hand_back_);
    });
    if (st.ok()) {
      ++tasks_done_;
      if (resp.has_next() && resp.next().has_task()) next_lease_ = resp.next();
      return;
    }
    if (!Transient(st.error_code()) || std::chrono::steady_clock::now() > give_up || hand_back_) {
      spdlog::warn("result of lease {} not delivered: {}", lease_id, st.error_message());
      return;
    }
    SleepUnlessStopping(backoff);
    backoff = std::min(backoff * 2, 2.0);
  }
}

void Worker::ReportFailure(const std::string& lease_id, const std::string& reason, bool hand_back) {
  v1::FailTaskRequest f;
  f.set_worker_id(worker_id_);
  f.set_lease_id(lease_id);
  f.set_reason(reason);
  f.set_hand_back(hand_back);
  v1::FailTaskResponse resp;
  grpc::ClientContext ctx;
  Prepare(&ctx, options_.rpc_timeout_s);
  grpc::Status st = stub_->FailTask(&ctx, f, &resp);
  if (!st.ok()) spdlog::warn("could not report the failure: {}", st.error_message());
}

}  // namespace lightfarm
