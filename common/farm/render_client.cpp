#include "common/farm/render_client.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <optional>
#include <thread>

#include "common/farm/content_hash.h"
#include "common/farm/farm_protocol.h"
#include "common/farm/proto_convert.h"
#include "common/scene/scene_cache.h"
#include "common/util/error.h"
#include "common/util/file.h"

namespace lightfarm {

namespace fs = std::filesystem;

namespace {

bool Retryable(grpc::StatusCode c) {
  return c == grpc::StatusCode::UNAVAILABLE || c == grpc::StatusCode::DEADLINE_EXCEEDED ||
         c == grpc::StatusCode::CANCELLED;
}

}  // namespace

RenderClient::RenderClient(std::shared_ptr<grpc::Channel> channel, std::string token, double timeout_s)
    : stub_(v1::RenderService::NewStub(channel)), token_(std::move(token)), timeout_s_(timeout_s) {}

void RenderClient::Prepare(grpc::ClientContext* ctx, double timeout_s) const { PrepareCall(ctx, token_, timeout_s); }

std::string RenderClient::UploadBlob(const std::string& data) {
  const std::string sha = Sha256Hex(data);
  grpc::ClientContext ctx;
  Prepare(&ctx, timeout_s_ + double(data.size()) / 1e6);  // a minute plus 1 s per MB
  v1::UploadBlobResponse resp;
  auto writer = stub_->UploadBlob(&ctx, &resp);
  ThrowIfError(WriteChunked(*writer, data.data(), data.size(), [&](v1::BlobChunk& chunk) {
    chunk.set_sha256(sha);
    chunk.set_total_size(data.size());
  }));
  return sha;
}

v1::SceneManifest RenderClient::UploadScene(const std::string& scene_path, bool strict) {
  // Every file the scene reads, relative to their deepest common directory. Paths stay as the
  // scene names them (made absolute, "." and ".." removed), symbolic links unresolved: a mesh
  // linked in from elsewhere keeps its place beside the file that names it.
  const auto as_named = [](const fs::path& p) { return fs::absolute(p).lexically_normal(); };
  std::vector<fs::path> files;
  std::optional<SceneDescription> parsed;
  try {
    // A file the scene names but that does not exist (a missing PLY) is not uploaded: building
    // the scene then fails with the directive's file:line, not with a hashing error.
    parsed = ParseSceneFile(scene_path);
    for (const std::string& f : parsed->files) {
      const fs::path named = as_named(f);
      if (fs::is_regular_file(named) && std::find(files.begin(), files.end(), named) == files.end())
        files.push_back(named);
    }
  } catch (const SceneError&) {
    if (strict) throw;
  }
  const fs::path root = as_named(scene_path);
  if (std::find(files.begin(), files.end(), root) == files.end()) files.insert(files.begin(), root);
  fs::path base = root.parent_path();
  for (const fs::path& f : files) {
    while (!base.empty() && base != base.root_path()) {
      auto rel = f.lexically_relative(base);
      if (!rel.empty() && *rel.begin() != "..") break;
      base = base.parent_path();
    }
  }
  v1::SceneManifest manifest;
  manifest.set_root(root.lexically_relative(base).generic_string());
  v1::FindMissingBlobsRequest query;
  std::map<std::string, std::string> path_of;
  for (const fs::path& f : files) {
    const std::string rel = f.lexically_relative(base).generic_string();
    v1::SceneFile* sf = manifest.add_files();
    sf->set_path(rel);
    sf->set_sha256(Sha256OfFile(f.string()));
    path_of[sf->sha256()] = f.string();
    query.add_sha256(sf->sha256());
  }
  const v1::FindMissingBlobsResponse missing = Call(&v1::RenderService::Stub::FindMissingBlobs, query);
  for (const std::string& sha : missing.missing()) UploadBlob(ReadFile(path_of.at(sha)));
  // A coordinator or worker in this process (an embedded render) takes the scene from here
  // instead of parsing it again.
  if (parsed)
    SceneCache::Process().Put(FromProto(manifest).ContentKey(), base.string(), manifest.root(), std::move(*parsed));
  return manifest;
}

std::string RenderClient::Submit(const v1::SceneManifest& scene, const RenderSettings& settings,
                                 int priority, const std::string& name) {
  v1::SubmitJobRequest req;
  *req.mutable_scene() = scene;
  *req.mutable_settings() = ToProto(settings);
  req.set_priority(priority);
  req.set_name(name);
  return Call(&v1::RenderService::Stub::SubmitJob, req).job_id();
}

v1::JobStatus RenderClient::GetJob(const std::string& job_id) {
  v1::GetJobRequest req;
  req.set_job_id(job_id);
  return Call(&v1::RenderService::Stub::GetJob, req);
}

std::vector<v1::JobStatus> RenderClient::ListJobs() {
  const v1::ListJobsResponse resp = Call(&v1::RenderService::Stub::ListJobs, v1::ListJobsRequest());
  return {resp.jobs().begin(), resp.jobs().end()};
}

v1::JobStatus RenderClient::Cancel(const std::string& job_id) {
  v1::GetJobRequest req;
  req.set_job_id(job_id);
  return Call(&v1::RenderService::Stub::CancelJob, req);
}

void RenderClient::Delete(const std::string& job_id) {
  v1::GetJobRequest req;
  req.set_job_id(job_id);
  Call(&v1::RenderService::Stub::DeleteJob, req);
}

v1::JobStatus RenderClient::SetPriority(const std::string& job_id, int priority) {
  v1::SetJobPriorityRequest req;
  req.set_job_id(job_id);
  req.set_priority(priority);
  return Call(&v1::RenderService::Stub::SetJobPriority, req);
}

std::vector<v1::WorkerStatus> RenderClient::ListWorkers() {
  const v1::ListWorkersResponse resp = Call(&v1::RenderService::Stub::ListWorkers, v1::ListWorkersRequest());
  return {resp.workers().begin(), resp.workers().end()};
}

v1::JobStatus RenderClient::Watch(const std::string& job_id,
                                  const std::function<void(const v1::JobStatus&)>& on_update,
                                  double max_wait_s, double preview_interval_s) {
  const auto give_up = std::chrono::steady_clock::now() +
                       std::chrono::milliseconds(int64_t(max_wait_s * 1000.0));
  int backoff_ms = 100;
  v1::JobStatus last;
  for (;;) {
    v1::GetJobRequest req;
    req.set_job_id(job_id);
    if (preview_interval_s > 0) {
      req.set_preview(true);
      req.set_preview_interval_s(preview_interval_s);
    }
    grpc::ClientContext ctx;
    Prepare(&ctx, max_wait_s);
    auto reader = stub_->WatchJob(&ctx, req);
    v1::JobStatus st;
    while (reader->Read(&st)) {
      backoff_ms = 100;
      last = st;
      if (on_update) on_update(st);
      if (IsTerminal(st.state())) {
        ctx.TryCancel();
        reader->Finish();
        return st;
      }
    }
    grpc::Status status = reader->Finish();
    if (!status.ok() && !Retryable(status.error_code())) throw RpcError(status);
    // The coordinator went away (restart, drain): try again until the overall deadline.
    if (std::chrono::steady_clock::now() > give_up)
      throw RpcError(grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, "job " + job_id + " did not finish in time"));
    std::this_thread::sleep_for(std::chrono::milliseconds(backoff_ms));
    backoff_ms = std::min(backoff_ms * 2, 2000);
  }
}

void RenderClient::Fetch(const std::string& job_id, std::string* exr, std::string* stats_json) {
  v1::GetJobRequest req;
  req.set_job_id(job_id);
  grpc::ClientContext ctx;
  Prepare(&ctx, timeout_s_ * 10);
  auto reader = stub_->FetchResult(&ctx, req);
  v1::ResultChunk chunk;
  exr->clear();
  bool first = true;
  uint64_t size = 0;
  std::string sha;
  while (reader->Read(&chunk)) {
    if (first) {
      *stats_json = chunk.stats_json();
      size = chunk.exr_size();
      sha = chunk.exr_sha256();
      exr->reserve(size);
      first = false;
    }
    exr->append(chunk.exr_data());
  }
  ThrowIfError(reader->Finish());
  if (first || exr->size() != size)
    throw std::runtime_error("job " + job_id + ": the result stream was truncated");
  if (!sha.empty()) {
    Sha256 hash;
    hash.Update(exr->data(), exr->size());
    const std::string got = hash.HexDigest();
    if (got != sha)
      throw std::runtime_error("job " + job_id + ": the result arrived corrupted (its bytes hash to " + got +
                               ", the coordinator sent " + sha + ")");
  }
}

}  // namespace lightfarm
