// A client of the coordinator's RenderService: what `lightfarm submit|status|watch|cancel|fetch`
// and the embedded `lightfarm render` use. Every call carries a deadline and the bearer token.
#pragma once

#include <grpcpp/grpcpp.h>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "common/render/render_job.h"
#include "common/farm/rpc.h"
#include "lightfarm/v1/render.grpc.pb.h"

namespace lightfarm {

class RenderClient {
 public:
  RenderClient(std::shared_ptr<grpc::Channel> channel, std::string token, double timeout_s = 60);

  // Collects the scene's files (the root, its includes, every file they reference), uploads the
  // ones the coordinator lacks, and returns the manifest. With strict = false a scene that does
  // not parse here is sent as its root file alone, so the coordinator reports the error on the
  // job; with strict = true the SceneError is thrown here.
  v1::SceneManifest UploadScene(const std::string& scene_path, bool strict);
  std::string UploadBlob(const std::string& data);  // returns its SHA-256

  std::string Submit(const v1::SceneManifest& scene, const RenderSettings& settings, int priority,
                     const std::string& name);
  v1::JobStatus GetJob(const std::string& job_id);
  std::vector<v1::JobStatus> ListJobs();
  v1::JobStatus Cancel(const std::string& job_id);
  void Delete(const std::string& job_id);
  v1::JobStatus SetPriority(const std::string& job_id, int priority);
  std::vector<v1::WorkerStatus> ListWorkers();
  // Follows the job until it ends, calling on_update for every status; reconnects (with the
  // same overall deadline) when the coordinator goes away and comes back. With
  // preview_interval_s > 0 the statuses carry a preview PNG of the finished tiles at most that often.
  v1::JobStatus Watch(const std::string& job_id,
                      const std::function<void(const v1::JobStatus&)>& on_update,
                      double max_wait_s = 7 * 24 * 3600.0, double preview_interval_s = 0);
  // The finished job's EXR bytes and stats JSON.
  void Fetch(const std::string& job_id, std::string* exr, std::string* stats_json);

 private:
  void Prepare(grpc::ClientContext* ctx, double timeout_s) const;
  // One unary RenderService call with the token and the default deadline; throws on error.
  template <typename Req, typename Resp>
  Resp Call(grpc::Status (v1::RenderService::Stub::*rpc)(grpc::ClientContext*, const Req&, Resp*),
            const Req& req) const {
    grpc::ClientContext ctx;
    Prepare(&ctx, timeout_s_);
    Resp resp;
    ThrowIfError((stub_.get()->*rpc)(&ctx, req, &resp));
    return resp;
  }
  std::unique_ptr<v1::RenderService::Stub> stub_;
  std::string token_;
  double timeout_s_;
};

}  // namespace lightfarm
