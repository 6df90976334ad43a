#include "coordinator/services.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <set>

#include "common/farm/farm_protocol.h"
#include "common/farm/proto_convert.h"
#include "common/util/file.h"

namespace lightfarm {

namespace {

// The scheduler's reports on the wire.
v1::JobStatus ToProto(const JobSnapshot& j) {
  v1::JobStatus st;
  st.set_job_id(j.job_id);
  st.set_state(lightfarm::ToProto(j.state));
  st.set_name(j.name);
  st.set_priority(j.priority);
  st.set_method(j.method);
  st.set_stage(j.stage);
  st.set_stage_count(j.stage_count);
  st.set_stage_name(j.stage_name);
  st.set_tasks_done(j.tasks_done);
  st.set_tasks_total(j.tasks_total);
  st.set_elapsed_s(j.elapsed_s);
  st.set_eta_s(j.eta_s);
  st.set_error(j.error);
  st.set_attempts(j.attempts);
  st.set_tasks_completed_total(j.tasks_completed_total);
  st.set_tasks_verified(j.tasks_verified);
  st.set_scene(j.scene);
  st.set_scene_sha256(j.scene_sha256);
  st.set_waiting(j.waiting);
  if (j.progressive) {
    st.set_progressive(true);
    st.set_passes_done(j.passes_done);
    st.set_passes_total(j.passes_total);
    st.set_noise_rel_stderr(j.noise_rel_stderr);
    st.set_noise_p90_rel_stderr(j.noise_p90_rel_stderr);
  }
  return st;
}

v1::WorkerStatus ToProto(const WorkerSnapshot& w) {
  v1::WorkerStatus st;
  st.set_worker_id(w.worker_id);
  st.set_name(w.name);
  st.set_version(w.version);
  st.set_threads(w.threads);
  st.set_lease_id(w.lease_id);
  st.set_job_id(w.job_id);
  st.set_last_seen_s(w.last_seen_s);
  st.set_alive(w.alive);
  st.set_tasks_done(w.tasks_done);
  st.set_tasks_failed(w.tasks_failed);
  for (const std::string& job : w.blocked_jobs) st.add_blocked_jobs(job);
  st.set_blocklisted(w.blocklisted);
  return st;
}

grpc::Status ToStatus(const FarmError& e) {
  using C = FarmError::Code;
  switch (e.code()) {
    case C::kInvalidArgument: return {grpc::StatusCode::INVALID_ARGUMENT, e.what()};
    case C::kNotFound: return {grpc::StatusCode::NOT_FOUND, e.what()};
    case C::kResourceExhausted: return {grpc::StatusCode::RESOURCE_EXHAUSTED, e.what()};
    case C::kFailedPrecondition: return {grpc::StatusCode::FAILED_PRECONDITION, e.what()};
    case C::kUnavailable: return {grpc::StatusCode::UNAVAILABLE, e.what()};
    case C::kDataLoss: return {grpc::StatusCode::DATA_LOSS, e.what()};
  }
  return {grpc::StatusCode::INTERNAL, e.what()};
}

// Runs fn and turns whatever it throws into a status; the coordinator survives any request.
template <typename Fn>
grpc::Status Guard(Fn&& fn) {
  try {
    fn();
    return grpc::Status::OK;
  } catch (const FarmError& e) {
    return ToStatus(e);
  } catch (const StorageFull& e) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED,
            std::string("the coordinator's disk is full; try again when space returns (") + e.what() + ")"};
  } catch (const std::exception& e) {
    spdlog::error("internal error: {}", e.what());
    return {grpc::StatusCode::INTERNAL, e.what()};
  }
}

const grpc::Status kUnauthenticated(grpc::StatusCode::UNAUTHENTICATED,
                                    "missing or wrong bearer token (authorization metadata)");

bool Authorized(const std::string& token, const grpc::CallbackServerContext* ctx) {
  if (token.empty()) return true;
  const auto& md = ctx->client_metadata();
  auto it = md.find("authorization");
  return it != md.end() && TokenMatches(token, std::string(it->second.data(), it->second.size()));
}


// A unary call: refused at once without the bearer token, else run on the pool with whatever it
// throws turned into its status.
template <typename Fn>
grpc::ServerUnaryReactor* GuardedUnary(grpc::CallbackServerContext* ctx, const std::string& token,
                                       ThreadPool* pool, Fn fn) {
  grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
  if (!Authorized(token, ctx)) {
    reactor->Finish(kUnauthenticated);
    return reactor;
  }
  pool->Submit([reactor, fn = std::move(fn)]() mutable { reactor->Finish(Guard(fn)); });
  return reactor;
}

}  // namespace

// --- streaming helpers ----------------------------------------------------------------------------

// Streams a file in chunks; `fill(msg, data, first)` builds each message.
template <typename Msg>
class FileStreamReactor : public grpc::ServerWriteReactor<Msg> {
 public:
  using Fill = std::function<void(Msg&, std::string&&, bool first)>;
  FileStreamReactor(ThreadPool* pool, std::string path, Fill fill)
      : pool_(pool), path_(std::move(path)), fill_(std::move(fill)) {
    pool_->Submit([this] {
      in_.open(path_, std::ios::binary);
      if (!in_) {
        this->Finish(grpc::Status(grpc::StatusCode::NOT_FOUND, "cannot read " + path_));
        return;
      }
      Next();
    });
  }
  void OnWriteDone(bool ok) override {
    if (!ok) {
      this->Finish(grpc::Status(grpc::StatusCode::CANCELLED, "client went away"));
      return;
    }
    pool_->Submit([this] { Next(); });
  }
  void OnDone() override { delete this; }

 private:
  void Next() {
    std::string data(kChunkBytes, '\0');
    in_.read(data.data(), std::streamsize(data.size()));
    data.resize(size_t(in_.gcount()));
    if (data.empty() && !first_) {
      this->Finish(grpc::Status::OK);
      return;
    }
    msg_.Clear();
    fill_(msg_, std::move(data), first_);
    first_ = false;
    this->StartWrite(&msg_);
  }
  ThreadPool* pool_;
  std::string path_;
  Fill fill_;
  std::ifstream in_;
  Msg msg_;
  bool first_ = true;
};

// Watchers of jobs: a thread polls each watched job a few times a second and writes a status
// when it changed, so the gRPC threads never wait on the coordinator.
class WatchReactor;
class WatchHub {
 public:
  explicit WatchHub(Coordinator& c) : coordinator_(c), thread_([this] { Loop(); }) {}
  ~WatchHub();
  void Add(WatchReactor* w) {
    std::lock_guard lock(mu_);
    watchers_.insert(w);
  }
  // From OnDone: the hub deletes the reactor after its current polling round.
  void Retire(WatchReactor* w) {
    std::lock_guard lock(mu_);
    watchers_.erase(w);
    retired_.push_back(w);
  }
  Coordinator& coordinator() { return coordinator_; }

 private:
  void Loop();
  Coordinator& coordinator_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::set<WatchReactor*> watchers_;
  std::vector<WatchReactor*> retired_;
  bool stopping_ = false;
  std::thread thread_;
};

class WatchReactor : public grpc::ServerWriteReactor<v1::JobStatus> {
 public:
  WatchReactor(WatchHub* hub, const v1::GetJobRequest& request)
      : hub_(hub),
        job_id_(request.job_id()),
        preview_(request.preview()),
        preview_interval_(std::chrono::duration<double>(
            request.preview_interval_s() > 0 ? std::clamp(request.preview_interval_s(), 0.25, 3600.0) : 2.0)) {
    hub_->Add(this);
  }
  // Called by the hub thread.
  void Poll() {
    std::lock_guard lock(mu_);
    if (writing_ || finished_) return;
    if (cancelled_) {
      finished_ = true;
      Finish(grpc::Status(grpc::StatusCode::CANCELLED, "watch cancelled"));
      return;
    }
    v1::JobStatus st;
    grpc::Status status = Guard([&] { st = ToProto(hub_->coordinator().GetJob(job_id_)); });
    if (!status.ok()) {
      finished_ = true;
      Finish(status);
      return;
    }
    v1::JobStatus cmp = st;
    cmp.clear_elapsed_s();
    cmp.clear_eta_s();
    const std::string key = cmp.SerializeAsString();
    const bool heartbeat = ++polls_since_write_ >= 40;  // elapsed/ETA refresh every ~2 s
    if (key == last_ && !heartbeat) return;
    last_ = key;
    polls_since_write_ = 0;
    final_ = IsTerminal(st.state());
    // Previews are made on this (the hub's) thread, never on a gRPC thread; the coordinator
    // shares the latest one between watchers.
    const auto now = std::chrono::steady_clock::now();
    if (preview_ && !final_ && now - last_preview_ >= preview_interval_) {
      JobPreview p;
      grpc::Status ps = Guard([&] {
        if (hub_->coordinator().Preview(job_id_, preview_tiles_, &p)) {
          st.set_preview_png(p.png);
          st.set_preview_width(uint32_t(p.width));
          st.set_preview_height(uint32_t(p.height));
          st.set_preview_tiles(p.tiles);
          preview_tiles_ = p.tiles;
          last_preview_ = now;
        }
      });
      if (!ps.ok()) spdlog::warn("preview of job {}: {}", job_id_, ps.error_message());
    }
    status_ = st;
    writing_ = true;
    StartWrite(&status_);
  }
  void OnWriteDone(bool ok) override {
    std::lock_guard lock(mu_);
    writing_ = false;
    if (!ok || final_) {
      finished_ = true;
      Finish(ok ? grpc::Status::OK : grpc::Status(grpc::StatusCode::CANCELLED, "client went away"));
    }
  }
  void OnCancel() override {
    std::lock_guard lock(mu_);
    cancelled_ = true;
  }
  void OnDone() override { hub_->Retire(this); }

 private:
  WatchHub* hub_;
  std::string job_id_;
  bool preview_ = false;
  std::chrono::duration<double> preview_interval_;
  std::chrono::steady_clock::time_point last_preview_{};
  uint64_t preview_tiles_ = 0;
  std::recursive_mutex mu_;  // a reaction may run inline inside StartWrite/Finish
  v1::JobStatus status_;
  std::string last_;
  int polls_since_write_ = 0;
  bool writing_ = false, final_ = false, finished_ = false, cancelled_ = false;
};

void WatchHub::Loop() {
  std::unique_lock lock(mu_);
  while (!stopping_) {
    cv_.wait_for(lock, std::chrono::milliseconds(50));
    std::vector<WatchReactor*> round(watchers_.begin(), watchers_.end());
    lock.unlock();
    for (WatchReactor* w : round) w->Poll();  // a retired reactor is finished: Poll is a no-op
    lock.lock();
    for (WatchReactor* w : retired_) delete w;
    retired_.clear();
  }
}

WatchHub::~WatchHub() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  thread_.join();
  for (WatchReactor* w : retired_) delete w;
}

// A client stream of chunks whose first message declares the payload's total size (blob
// uploads, task results). The reader enforces what every such stream must: a first message, a
// declared size within the limit, never more data than declared, and nothing missing at the
// end; the handlers (run on the pool, one at a time) see only data that passed, and whatever
// they throw becomes the call's status (Guard).
template <typename Msg>
class SizedStreamReader : public grpc::ServerReadReactor<Msg> {
 public:
  struct Handlers {
    std::string what;          // names the payload in errors: "blob", "result"
    uint64_t limit = 0;        // largest declared size accepted
    std::string limit_option;  // the option that sets it, for the error message
    // The first message's header: checks it (throwing FarmError) and returns the declared size.
    std::function<uint64_t(const Msg&)> open;
    std::function<void(const std::string&)> append;  // every message's data, in order
    std::function<void()> close;                     // all of it arrived: finish, fill the response
  };
  SizedStreamReader(ThreadPool* pool, Handlers handlers) : pool_(pool), h_(std::move(handlers)) {
    this->StartRead(&msg_);
  }
  void OnReadDone(bool ok) override {
    pool_->Submit([this, ok] {
      const grpc::Status st = Guard([&] { ok ? Chunk() : End(); });
      if (!ok || !st.ok()) {
        this->Finish(st);
        return;
      }
      this->StartRead(&msg_);
    });
  }
  void OnDone() override { delete this; }

 private:
  void Chunk() {
    if (!opened_) {
      size_ = h_.open(msg_);
      opened_ = true;
      if (size_ > h_.limit)
        throw FarmError(FarmError::Code::kResourceExhausted,
                        h_.what + " of " + std::to_string(size_) + " bytes exceeds the limit of " +
                            std::to_string(h_.limit) + " bytes (" + h_.limit_option + ")");
    }
    received_ += msg_.data().size();
    if (received_ > size_)
      throw FarmError(FarmError::Code::kInvalidArgument,
                      h_.what + ": more data than the declared " + std::to_string(size_) + " bytes");
    h_.append(msg_.data());
  }
  void End() {
    if (!opened_) throw FarmError(FarmError::Code::kInvalidArgument, "empty " + h_.what + " stream");
    if (received_ != size_)
      throw FarmError(FarmError::Code::kInvalidArgument, h_.what + " stream ended after " + std::to_string(received_) +
                                                             " of its " + std::to_string(size_) + " bytes");
    h_.close();
  }

  ThreadPool* pool_;
  Handlers h_;
  Msg msg_;
  bool opened_ = false;
  uint64_t size_ = 0, received_ = 0;
};

template <typename Msg>
class RejectReadReactor : public grpc::ServerReadReactor<Msg> {
 public:
  explicit RejectReadReactor(const grpc::Status& st) { this->Finish(st); }
  void OnDone() override { delete this; }
};
template <typename Msg>
class RejectWriteReactor : public grpc::ServerWriteReactor<Msg> {
 public:
  explicit RejectWriteReactor(const grpc::Status& st) { this->Finish(st); }
  void OnDone() override { delete this; }
};

// --- RenderService ----------------------------------------------------------------------------------

class FarmServer::RenderServiceImpl final : public v1::RenderService::CallbackService {
 public:
  RenderServiceImpl(Coordinator& c, ThreadPool* pool, WatchHub* hub, std::string token)
      : c_(c), pool_(pool), hub_(hub), token_(std::move(token)) {}

  template <typename Fn>
  grpc::ServerUnaryReactor* Unary(grpc::CallbackServerContext* ctx, Fn fn) {
    return GuardedUnary(ctx, token_, pool_, std::move(fn));
  }

  grpc::ServerUnaryReactor* FindMissingBlobs(grpc::CallbackServerContext* ctx,
                                             const v1::FindMissingBlobsRequest* req,
                                             v1::FindMissingBlobsResponse* resp) override {
    return Unary(ctx, [this, req, resp] {
      std::vector<std::string> hashes(req->sha256().begin(), req->sha256().end());
      for (const std::string& h : c_.FindMissingBlobs(hashes)) resp->add_missing(h);
    });
  }

  grpc::ServerReadReactor<v1::BlobChunk>* UploadBlob(grpc::CallbackServerContext* ctx,
                                                     v1::UploadBlobResponse* resp) override {
    if (!Authorized(token_, ctx)) return new RejectReadReactor<v1::BlobChunk>(kUnauthenticated);
    // A blob the store already has is read to the end and dropped.
    struct State {
      std::unique_ptr<BlobStore::Upload> upload;
      std::string sha;
      uint64_t size = 0;
      bool skip = false;
    };
    auto state = std::make_shared<State>();
    BlobStore& blobs = c_.blobs();
    SizedStreamReader<v1::BlobChunk>::Handlers h;
    h.what = "blob";
    h.limit = blobs.max_blob_bytes();
    h.limit_option = "--max-blob-mb";
    h.open = [this, state, &blobs](const v1::BlobChunk& chunk) {
      state->sha = chunk.sha256();
      state->size = chunk.total_size();
      if (!IsSha256Hex(state->sha))
        throw FarmError(FarmError::Code::kInvalidArgument, "the first chunk must name the blob's SHA-256 (lower-case hex)");
      state->skip = blobs.Has(state->sha);
      if (state->skip) blobs.Touch(state->sha);  // asked for again: kept through the grace period
      if (!state->skip && c_.storage_full())
        throw FarmError(FarmError::Code::kResourceExhausted, c_.StorageFullMessage());
      return state->size;
    };
    h.append = [state, &blobs](const std::string& data) {
      if (state->skip) return;
      if (!state->upload) state->upload = std::make_unique<BlobStore::Upload>(&blobs, state->sha, state->size);
      state->upload->Append(data);
    };
    h.close = [state, resp] {
      if (state->upload) {
        try {
          state->upload->Commit();
        } catch (const std::invalid_argument& e) {
          throw FarmError(FarmError::Code::kInvalidArgument, e.what());
        }
      }
      resp->set_sha256(state->sha);
      resp->set_size(state->size);
    };
    return new SizedStreamReader<v1::BlobChunk>(pool_, std::move(h));
  }

  grpc::ServerUnaryReactor* SubmitJob(grpc::CallbackServerContext* ctx, const v1::SubmitJobRequest* req,
                                      v1::SubmitJobResponse* resp) override {
    return Unary(ctx, [this, req, resp] {
      resp->set_job_id(c_.Submit(JobRequest{req->name(), req->priority(), FromProto(req->scene()), FromProto(req->settings())}));
    });
  }
  grpc::ServerUnaryReactor* GetJob(grpc::CallbackServerContext* ctx, const v1::GetJobRequest* req,
                                   v1::JobStatus* resp) override {
    return Unary(ctx, [this, req, resp] { *resp = ToProto(c_.GetJob(req->job_id())); });
  }
  grpc::ServerUnaryReactor* ListJobs(grpc::CallbackServerContext* ctx, const v1::ListJobsRequest*,
                                     v1::ListJobsResponse* resp) override {
    return Unary(ctx, [this, resp] {
      for (const JobSnapshot& s : c_.ListJobs()) *resp->add_jobs() = ToProto(s);
    });
  }
  grpc::ServerUnaryReactor* DeleteJob(grpc::CallbackServerContext* ctx, const v1::GetJobRequest* req,
                                      v1::DeleteJobResponse*) override {
    return Unary(ctx, [this, req] { c_.Delete(req->job_id()); });
  }

  grpc::ServerUnaryReactor* CancelJob(grpc::CallbackServerContext* ctx, const v1::GetJobRequest* req,
                                      v1::JobStatus* resp) override {
    return Unary(ctx, [this, req, resp] { *resp = ToProto(c_.Cancel(req->job_id())); });
  }
  grpc::ServerUnaryReactor* SetJobPriority(grpc::CallbackServerContext* ctx, const v1::SetJobPriorityRequest* req,
                                           v1::JobStatus* resp) override {
    return Unary(ctx, [this, req, resp] { *resp = ToProto(c_.SetPriority(req->job_id(), req->priority())); });
  }
  grpc::ServerUnaryReactor* ListWorkers(grpc::CallbackServerContext* ctx, const v1::ListWorkersRequest*,
                                        v1::ListWorkersResponse* resp) override {
    return Unary(ctx, [this, resp] {
      for (const WorkerSnapshot& w : c_.ListWorkers()) *resp->add_workers() = ToProto(w);
    });
  }

  grpc::ServerWriteReactor<v1::JobStatus>* WatchJob(grpc::CallbackServerContext* ctx,
                                                   const v1::GetJobRequest* req) override {
    if (!Authorized(token_, ctx)) return new RejectWriteReactor<v1::JobStatus>(kUnauthenticated);
    return new WatchReactor(hub_, *req);
  }

  grpc::ServerWriteReactor<v1::ResultChunk>* FetchResult(grpc::CallbackServerContext* ctx,
                                                        const v1::GetJobRequest* req) override {
    if (!Authorized(token_, ctx)) return new RejectWriteReactor<v1::ResultChunk>(kUnauthenticated);
    JobResult result;
    grpc::Status st = Guard([&] { result = c_.GetResult(req->job_id()); });
    if (!st.ok()) return new RejectWriteReactor<v1::ResultChunk>(st);
    std::string stats = result.stats_json, sha = result.exr_sha256;
    uint64_t size = std::filesystem::file_size(result.exr_path);
    return new FileStreamReactor<v1::ResultChunk>(
        pool_, result.exr_path, [stats, sha, size](v1::ResultChunk& m, std::string&& data, bool first) {
          if (first) {
            m.set_stats_json(stats);
            m.set_exr_size(size);
            m.set_exr_sha256(sha);
          }
          m.set_exr_data(std::move(data));
        });
  }

 private:
  Coordinator& c_;
  ThreadPool* pool_;
  WatchHub* hub_;
  std::string token_;
};

// --- WorkerService ----------------------------------------------------------------------------------

class FarmServer::WorkerServiceImpl final : public v1::WorkerService::CallbackService {
 public:
  WorkerServiceImpl(Coordinator& c, ThreadPool* pool, std::string token)
      : c_(c), pool_(pool), token_(std::move(token)) {}

  template <typename Fn>
  grpc::ServerUnaryReactor* Unary(grpc::CallbackServerContext* ctx, Fn fn) {
    return GuardedUnary(ctx, token_, pool_, std::move(fn));
  }

  grpc::ServerUnaryReactor* Register(grpc::CallbackServerContext* ctx, const v1::RegisterRequest* req,
                                     v1::RegisterResponse* resp) override {
    return Unary(ctx, [this, req, resp] {
      resp->set_worker_id(c_.RegisterWorker(req->name(), req->protocol_version(), req->software_version(),
                                            req->threads()));
      resp->set_lease_timeout_ms(c_.lease_timeout_ms());
    });
  }
  grpc::ServerUnaryReactor* LeaseTask(grpc::CallbackServerContext* ctx, const v1::LeaseTaskRequest* req,
                                      v1::LeaseTaskResponse* resp) override {
    return Unary(ctx, [this, req, resp, ctx] {
      if (ctx->IsCancelled()) return;  // the worker gave up waiting; do not lease to nobody
      FillLease(c_.Lease(req->worker_id()), resp);
    });
  }
  grpc::ServerUnaryReactor* Heartbeat(grpc::CallbackServerContext* ctx, const v1::HeartbeatRequest* req,
                                      v1::HeartbeatResponse* resp) override {
    return Unary(ctx, [this, req, resp] { resp->set_keep_going(c_.Heartbeat(req->worker_id(), req->lease_id())); });
  }
  grpc::ServerUnaryReactor* FailTask(grpc::CallbackServerContext* ctx, const v1::FailTaskRequest* req,
                                     v1::FailTaskResponse*) override {
    return Unary(ctx, [this, req] { c_.Fail(req->worker_id(), req->lease_id(), req->reason(), req->hand_back()); });
  }

  grpc::ServerReadReactor<v1::TaskResultChunk>* CompleteTask(grpc::CallbackServerContext* ctx,
                                                             v1::CompleteTaskResponse* resp) override {
    if (!Authorized(token_, ctx)) return new RejectReadReactor<v1::TaskResultChunk>(kUnauthenticated);
    struct State {
      std::string worker, lease;
      bool lease_next = false;
      Bytes data;
    };
    auto state = std::make_shared<State>();
    SizedStreamReader<v1::TaskResultChunk>::Handlers h;
    h.what = "result";
    h.limit = c_.options().max_result_bytes;
    h.limit_option = "the coordinator's result limit";
    h.open = [state](const v1::TaskResultChunk& chunk) {
      state->worker = chunk.worker_id();
      state->lease = chunk.lease_id();
      state->lease_next = chunk.lease_next();
      state->data.reserve(std::min<uint64_t>(chunk.total_size(), uint64_t(kMaxMessageBytes)));
      return uint64_t(chunk.total_size());
    };
    h.append = [state](const std::string& data) { state->data.insert(state->data.end(), data.begin(), data.end()); };
    h.close = [this, state, resp] {
      resp->set_accepted(c_.Complete(state->worker, state->lease, state->data));
      if (!state->lease_next) return;
      // The completion is recorded: a failing lease must not turn it into an error the worker
      // would retry. It leases on its own instead.
      try {
        FillLease(c_.Lease(state->worker), resp->mutable_next());
      } catch (const std::exception&) {
        resp->clear_next();
      }
    };
    return new SizedStreamReader<v1::TaskResultChunk>(pool_, std::move(h));
  }

  grpc::ServerWriteReactor<v1::BlobChunk>* FetchBlob(grpc::CallbackServerContext* ctx,
                                                     const v1::FetchBlobRequest* req) override {
    if (!Authorized(token_, ctx)) return new RejectWriteReactor<v1::BlobChunk>(kUnauthenticated);
    if (!c_.blobs().Has(req->sha256()))
      return new RejectWriteReactor<v1::BlobChunk>(
          grpc::Status(grpc::StatusCode::NOT_FOUND, "no blob " + req->sha256().substr(0, 80)));
    // Checked against its name before it is streamed: a corrupted blob is quarantined (and the
    // task that needs it fails, naming the corruption) instead of reaching a worker's cache.
    if (!c_.blobs().Verify(req->sha256())) {
      c_.OnBlobCorrupted(req->sha256());  // the jobs that need it make it again
      return new RejectWriteReactor<v1::BlobChunk>(grpc::Status(
          grpc::StatusCode::DATA_LOSS, "blob " + req->sha256() + " is corrupted on the coordinator's disk (quarantined)"));
    }
    std::string sha = req->sha256();
    uint64_t size = c_.blobs().Size(sha);
    return new FileStreamReactor<v1::BlobChunk>(
        pool_, c_.blobs().Path(sha), [sha, size](v1::BlobChunk& m, std::string&& data, bool first) {
          if (first) {
            m.set_sha256(sha);
            m.set_total_size(size);
          }
          m.set_data(std::move(data));
        });
  }

 private:
  void FillLease(LeaseGrant g, v1::LeaseTaskResponse* resp) {
    resp->set_has_task(g.has_task);
    resp->set_lease_timeout_ms(c_.lease_timeout_ms());
    if (!g.has_task) return;
    resp->set_lease_id(g.lease_id);
    v1::JobContext& job = *resp->mutable_job();
    job.set_job_id(g.job.job_id);
    *job.mutable_scene() = ToProto(g.job.manifest);
    *job.mutable_settings() = ToProto(g.job.settings);
    job.set_clamp(g.job.clamp);
    job.set_lights_sha256(g.job.lights_sha);
    job.set_receivers_sha256(g.job.receivers_sha);
    resp->set_task(std::string(g.task.begin(), g.task.end()));
    resp->set_artifact_sha256(g.artifact_sha);
  }

  Coordinator& c_;
  ThreadPool* pool_;
  std::string token_;
};

// --- server ---------------------------------------------------------------------------------------

FarmServer::FarmServer(Coordinator& coordinator, const ServerConfig& config) : coordinator_(coordinator) {
  pool_ = std::make_unique<ThreadPool>(std::max(1, config.rpc_threads));
  watch_hub_ = std::make_unique<WatchHub>(coordinator);
  render_service_ = std::make_unique<RenderServiceImpl>(coordinator, pool_.get(), watch_hub_.get(), config.token);
  worker_service_ = std::make_unique<WorkerServiceImpl>(coordinator, pool_.get(), config.token);

  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.SetMaxReceiveMessageSize(kMaxMessageBytes);
  builder.SetMaxSendMessageSize(kMaxMessageBytes);
  if (!config.listen.empty()) {
    std::shared_ptr<grpc::ServerCredentials> creds;
    if (!config.tls_cert.empty() || !config.tls_key.empty()) {
      if (config.tls_cert.empty() || config.tls_key.empty())
        throw std::invalid_argument("--tls-cert and --tls-key must be given together");
      grpc::SslServerCredentialsOptions ssl;
      ssl.pem_key_cert_pairs.push_back({ReadFile(config.tls_key), ReadFile(config.tls_cert)});
      creds = grpc::SslServerCredentials(ssl);
    } else {
      creds = grpc::InsecureServerCredentials();
    }
    builder.AddListeningPort(config.listen, creds, &port_);
  }
  builder.RegisterService(render_service_.get());
  builder.RegisterService(worker_service_.get());
  server_ = builder.BuildAndStart();
  if (!server_ || (!config.listen.empty() && port_ == 0))
    throw std::runtime_error("cannot listen on " + config.listen);

  if (!config.metrics_listen.empty())
    metrics_ = std::make_unique<HttpServer>(coordinator_, HttpConfig{config.metrics_listen, "", false, true, ""});
  if (!config.http_listen.empty())
    http_ = std::make_unique<HttpServer>(
        coordinator_, HttpConfig{config.http_listen, config.token, config.http_allow_open, false, config.bench_dir});
}

FarmServer::~FarmServer() { Shutdown(0); }

std::shared_ptr<grpc::Channel> FarmServer::InProcessChannel() {
  return server_->InProcessChannel(FarmChannelArguments());
}

void FarmServer::Shutdown(double grace_seconds) {
  if (shut_down_) return;
  shut_down_ = true;
  coordinator_.SetDraining();
  if (auto* health = server_->GetHealthCheckService()) health->SetServingStatus(false);
  server_->Shutdown(std::chrono::system_clock::now() +
                    std::chrono::milliseconds(int64_t(grace_seconds * 1000)));
  watch_hub_.reset();
  pool_->Stop();
  if (metrics_) metrics_->Stop();
  if (http_) http_->Stop();
}

}  // namespace lightfarm
