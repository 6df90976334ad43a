// A farm worker: registers with the coordinator (version handshake), then pulls tasks: lease,
// fetch and cache the job's blobs by hash, rebuild the scene and lighting matrix (cached per job),
// run the task with oneTBB while heartbeating, stream the result back. Reconnects with backoff
// when the coordinator is away. No inbound port.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <list>
#include <map>
#include <memory>
#include <optional>
#include <mutex>
#include <stdexcept>
#include <string>

#include "common/render/render_job.h"
#include "common/farm/farm_protocol.h"
#include "lightfarm/v1/worker.grpc.pb.h"

namespace lightfarm {

// The coordinator refused this worker for good (incompatible version, wrong token).
class WorkerRefused : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct WorkerOptions {
  std::string name;                   // default: host-pid
  std::string token;
  std::string cache_dir;              // default: a temporary directory, removed at exit
  uint64_t cache_bytes = 4ull << 30;  // blob cache bound (least recently used blobs go first)
  uint32_t protocol_version = kWorkerProtocolVersion;  // tests pretend to be an old worker
  std::string software_version = LIGHTFARM_VERSION;
  double rpc_timeout_s = 30;
  double idle_poll_s = 0.2;           // pause between LeaseTask calls while there is no task
  int threads = 0;                    // reported to the coordinator (0: all cores)
};

// Blobs by SHA-256 under a directory, bounded in total size (LRU).
class BlobCache {
 public:
  BlobCache(std::string dir, uint64_t max_bytes);
  bool Has(const std::string& sha);
  std::string Path(const std::string& sha) const { return dir_ + "/" + sha; }
  // Moves a verified temporary file into the cache and evicts beyond the bound.
  void Adopt(const std::string& sha, const std::string& tmp_path);
  // Drops a cached blob (one whose bytes no longer hash to its name).
  void Forget(const std::string& sha);
  std::string TempPath();

 private:
  void Touch(const std::string& sha, uint64_t size);
  std::string dir_;
  uint64_t max_bytes_, total_ = 0, counter_ = 0;
  std::list<std::string> lru_;  // front: most recent
  std::map<std::string, std::pair<uint64_t, std::list<std::string>::iterator>> entries_;
  std::mutex mu_;
};

class Worker {
 public:
  Worker(std::shared_ptr<grpc::Channel> channel, WorkerOptions options);
  ~Worker();

  // Registers and runs tasks until Stop(). Throws WorkerRefused.
  void Run();
  // Drain: finish the current task, then Run returns. hand_back: give it back immediately.
  void Stop(bool hand_back = false);
  uint64_t tasks_done() const { return tasks_done_; }
  uint64_t tasks_cancelled() const { return tasks_cancelled_; }  // stopped because the lease was lost

 private:
  struct JobRuntime;
  struct LeasedTask;
  enum class Ending { kDone, kHandedBack, kLeaseLost };
  void Register();
  // One task: lease, prepare, run under heartbeats, deliver. False when there was nothing to do.
  bool RunOneTask();
  // The task of a lease with what it needs (plan, spec, the previous stage's artifact); throws.
  LeasedTask PrepareTask(const v1::LeaseTaskResponse& lease);
  // Runs it while heartbeating the lease; stops it when the lease is lost or on hand-back.
  Ending RunUnderLease(const LeasedTask& leased, const std::string& lease_id, TaskOutput* output);
  // Streams the result back, retrying while the coordinator is away.
  void DeliverResult(const std::string& lease_id, const TaskOutput& output);
  void ReportFailure(const std::string& lease_id, const std::string& reason, bool hand_back);
  std::shared_ptr<JobRuntime> Runtime(const v1::JobContext& ctx);
  std::string FetchBlob(const std::string& sha);  // path of the cached blob
  void Prepare(grpc::ClientContext* ctx, double timeout_s) const;
  void SleepUnlessStopping(double seconds);

  std::unique_ptr<v1::WorkerService::Stub> stub_;
  WorkerOptions options_;
  std::string temp_dir_;  // removed at destruction when cache_dir was not given
  std::unique_ptr<BlobCache> cache_;
  std::string worker_id_;
  uint32_t lease_timeout_ms_ = 30000;
  std::shared_ptr<JobRuntime> runtime_;  // the last job's scene and matrix
  std::atomic<bool> stop_{false}, hand_back_{false};
  std::optional<v1::LeaseTaskResponse> next_lease_;  // leased with the last completion
  std::atomic<uint64_t> tasks_done_{0}, tasks_cancelled_{0};
  std::atomic<uint64_t> cache_corrupted_{0};  // cached blobs found corrupted and fetched again
  std::mutex sleep_mu_;
  std::condition_variable sleep_cv_;
};

}  // namespace lightfarm
