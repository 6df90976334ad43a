// A real coordinator on loopback under malformed, oversized and out-of-order RPCs, sent with the
// generated stubs (and raw bytes) instead of the CLI or the worker: every call gets its precise
// status code, nothing it sends can fail a job it has no lease on, and the coordinator still
// serves a normal job afterwards.
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <thread>

#include <grpcpp/generic/generic_stub.h>

#include "common/render/serialize.h"
#include "coordinator/coordinator.h"
#include "lightfarm/v1/worker.grpc.pb.h"
#include "tests/integration/farm_harness.h"

namespace lightfarm {
namespace test_farm_bad_rpcs {

using namespace lightfarm::testing;
using grpc::StatusCode;

std::shared_ptr<grpc::Channel> Channel(const CoordinatorProcess& c) {
  ChannelOptions o;
  o.address = c.address();
  return MakeChannel(o);
}

template <typename Call>
grpc::Status Unary(Call call) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  return call(&ctx);
}

// The code of a RenderClient call, OK when it returned.
template <typename Fn>
StatusCode CodeOf(Fn fn) {
  try {
    fn();
    return StatusCode::OK;
  } catch (const RpcError& e) {
    return e.code();
  }
}

// Sends `bytes` as the request of `method` without any protobuf encoding.
grpc::Status RawCall(const std::shared_ptr<grpc::Channel>& channel, const std::string& method,
                     const std::string& bytes) {
  grpc::GenericStub stub(channel);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  grpc::Slice slice(bytes);
  grpc::ByteBuffer request(&slice, 1), response;
  std::promise<grpc::Status> done;
  stub.UnaryCall(&ctx, method, grpc::StubOptions(), &request, &response,
                 [&](grpc::Status st) { done.set_value(st); });
  return done.get_future().get();
}

// CompleteTask with the given chunks.
grpc::Status Complete(v1::WorkerService::Stub& stub, const std::vector<v1::TaskResultChunk>& chunks) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  v1::CompleteTaskResponse resp;
  auto writer = stub.CompleteTask(&ctx, &resp);
  for (const v1::TaskResultChunk& c : chunks)
    if (!writer->Write(c)) break;
  writer->WritesDone();
  return writer->Finish();
}

v1::TaskResultChunk ResultChunk(const std::string& worker, const std::string& lease,
                                const std::string& data, uint64_t declared) {
  v1::TaskResultChunk c;
  c.set_worker_id(worker);
  c.set_lease_id(lease);
  c.set_total_size(declared);
  c.set_data(data);
  return c;
}

TEST(FarmBadRpcs, RenderServiceGivesPreciseCodesForMalformedAndOversizedRequests) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"),
                                 {"--max-blob-mb", "1", "--max-resolution", "4096", "--max-lights", "1000000"});
  auto channel = Channel(coordinator);
  auto stub = v1::RenderService::NewStub(channel);
  RenderClient client = coordinator.Client();
  const std::string scene = dir.Write("tiny.pbrt", kTinyScene);
  const v1::SceneManifest manifest = client.UploadScene(scene, true);

  auto submit = [&](const std::function<void(v1::SubmitJobRequest&)>& edit) {
    v1::SubmitJobRequest req;
    *req.mutable_scene() = manifest;
    req.mutable_settings()->set_method("brute");
    req.mutable_settings()->set_lights(10);
    edit(req);
    v1::SubmitJobResponse resp;
    return Unary([&](grpc::ClientContext* ctx) { return stub->SubmitJob(ctx, req, &resp); }).error_code();
  };
  EXPECT_EQ(submit([](auto&) {}), StatusCode::OK);
  // Malformed settings are INVALID_ARGUMENT, configured limits RESOURCE_EXHAUSTED.
  EXPECT_EQ(submit([](auto& r) { r.mutable_settings()->set_width(-8); }), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(submit([](auto& r) { r.mutable_settings()->set_height(-1); }), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(submit([](auto& r) { r.mutable_settings()->set_spp(-3); }), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(submit([](auto& r) { r.mutable_settings()->set_width(1 << 30); }), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_EQ(submit([](auto& r) { r.mutable_settings()->set_lights(uint64_t(1) << 62); }),
            StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_EQ(submit([](auto& r) { r.mutable_settings()->set_method("nope"); }), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(submit([](auto& r) {
              r.mutable_settings()->set_method("sparse-completion");
              r.mutable_settings()->add_params("rank=abc");
            }),
            StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(submit([](auto& r) { r.mutable_settings()->add_params("=1"); }), StatusCode::INVALID_ARGUMENT);
  // Malformed manifests.
  EXPECT_EQ(submit([](auto& r) { r.clear_scene(); }), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(submit([](auto& r) { r.mutable_scene()->set_root("other.pbrt"); }), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(submit([](auto& r) { r.mutable_scene()->mutable_files(0)->set_sha256("xyz"); }),
            StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(submit([](auto& r) { r.mutable_scene()->mutable_files(0)->set_path("/etc/passwd"); }),
            StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(submit([](auto& r) { *r.mutable_scene()->add_files() = r.scene().files(0); }),
            StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(submit([](auto& r) { r.mutable_scene()->mutable_files(0)->set_sha256(std::string(64, 'b')); }),
            StatusCode::FAILED_PRECONDITION);
  // A message beyond the 64 MiB limit: a 65 MiB job name, and a huge repeated field.
  EXPECT_EQ(submit([](auto& r) { r.set_name(std::string(65u << 20, 'n')); }), StatusCode::RESOURCE_EXHAUSTED);
  {
    v1::FindMissingBlobsRequest req;
    for (int i = 0; i < 1200000; ++i) req.add_sha256(std::string(64, 'a'));  // ~80 MiB
    v1::FindMissingBlobsResponse resp;
    EXPECT_EQ(Unary([&](grpc::ClientContext* ctx) { return stub->FindMissingBlobs(ctx, req, &resp); }).error_code(),
              StatusCode::RESOURCE_EXHAUSTED);
    v1::FindMissingBlobsRequest bad;
    bad.add_sha256("not hex");
    EXPECT_EQ(Unary([&](grpc::ClientContext* ctx) { return stub->FindMissingBlobs(ctx, bad, &resp); }).error_code(),
              StatusCode::INVALID_ARGUMENT);
  }
  // An empty (valid) message through the raw path: the method's own error.
  EXPECT_EQ(RawCall(channel, "/lightfarm.v1.RenderService/GetJob", "").error_code(), StatusCode::INVALID_ARGUMENT);
  // Bytes that are no protobuf at all: gRPC's callback server answers UNIMPLEMENTED itself (the
  // handler never runs; measured with grpc 1.51), and the coordinator is unaffected.
  for (const char* method : {"/lightfarm.v1.RenderService/SubmitJob", "/lightfarm.v1.RenderService/GetJob",
                             "/lightfarm.v1.WorkerService/Heartbeat"}) {
    const grpc::Status st = RawCall(channel, method, std::string("\xff\xff\xff\xff\x0f garbage", 13));
    EXPECT_EQ(st.error_code(), StatusCode::UNIMPLEMENTED) << method << ": " << st.error_message();
  }
  EXPECT_EQ(RawCall(channel, "/lightfarm.v1.RenderService/NoSuchMethod", "").error_code(),
            StatusCode::UNIMPLEMENTED);
  // Blob uploads: no hash, a wrong hash, too big, more data than declared, empty.
  auto upload = [&](const std::vector<v1::BlobChunk>& chunks) {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    v1::UploadBlobResponse resp;
    auto writer = stub->UploadBlob(&ctx, &resp);
    for (const v1::BlobChunk& c : chunks)
      if (!writer->Write(c)) break;
    writer->WritesDone();
    return writer->Finish().error_code();
  };
  auto chunk = [](const std::string& sha, uint64_t size, const std::string& data) {
    v1::BlobChunk c;
    c.set_sha256(sha);
    c.set_total_size(size);
    c.set_data(data);
    return c;
  };
  EXPECT_EQ(upload({chunk("", 3, "abc")}), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(upload({chunk(std::string(64, 'c'), 3, "abc")}), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(upload({chunk(std::string(64, 'c'), 2u << 20, "abc")}), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_EQ(upload({chunk(std::string(64, 'c'), 2, "abc")}), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(upload({chunk(std::string(64, 'c'), 10, "abc")}), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(upload({}), StatusCode::INVALID_ARGUMENT);

  // Unknown job ids, on every RPC that takes one: not a number → INVALID_ARGUMENT, a number the
  // coordinator never issued → NOT_FOUND.
  for (const auto& [id, code] : std::vector<std::pair<std::string, StatusCode>>{
           {"nope", StatusCode::INVALID_ARGUMENT}, {"", StatusCode::INVALID_ARGUMENT},
           {"12abc", StatusCode::INVALID_ARGUMENT}, {"99999999999999999999999", StatusCode::INVALID_ARGUMENT},
           {"987654", StatusCode::NOT_FOUND}, {"-1", StatusCode::NOT_FOUND}}) {
    EXPECT_EQ(CodeOf([&] { client.GetJob(id); }), code) << "GetJob " << id;
    EXPECT_EQ(CodeOf([&] { client.Cancel(id); }), code) << "CancelJob " << id;
    EXPECT_EQ(CodeOf([&] { client.Watch(id, [](const v1::JobStatus&) {}); }), code) << "WatchJob " << id;
    std::string exr, stats;
    EXPECT_EQ(CodeOf([&] { client.Fetch(id, &exr, &stats); }), code) << "FetchResult " << id;
  }

  // A scene of garbage bytes is accepted (the blobs exist) and its job fails naming the file.
  const std::string garbage = dir.Write("garbage.pbrt", std::string("\x01\x02\xff\xfe garbage \"", 14));
  auto worker = StartWorker(dir, coordinator.address());
  const std::string bad_job = client.Submit(client.UploadScene(garbage, false), RenderSettings{}, 0, "garbage");
  const v1::JobStatus bad = WaitForJob(client, bad_job, [](const v1::JobStatus&) { return false; }, 120);
  EXPECT_EQ(bad.state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(bad.error().find("garbage.pbrt:"), std::string::npos) << bad.error();
  // Regression: the error quoted the file's bytes, invalid UTF-8 in a proto3 string, and every
  // status holding it failed to parse on the client: GetJob (above, it never returned), ListJobs.
  EXPECT_EQ(CodeOf([&] { client.ListJobs(); }), StatusCode::OK);
  // Options the plan reads (not the method) are checked when the job is planned: the job fails
  // naming the option. (Not INVALID_ARGUMENT at submit: see docs/robustness.md.)
  RenderSettings bad_clamp;
  bad_clamp.params = {"clamp=abc"};
  const std::string clamp_job = client.Submit(client.UploadScene(scene, true), bad_clamp, 0, "");
  const v1::JobStatus clamp_status =
      WaitForJob(client, clamp_job, [](const v1::JobStatus&) { return false; }, 120);
  EXPECT_EQ(clamp_status.state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(clamp_status.error().find("clamp"), std::string::npos) << clamp_status.error();
  // Fetching a failed job's result is a precondition failure.
  std::string exr, stats;
  EXPECT_EQ(CodeOf([&] { client.Fetch(bad_job, &exr, &stats); }), StatusCode::FAILED_PRECONDITION);

  // Still serving: a normal job completes.
  CliResult ok = RunCli(dir, {"submit", scene, "--server", coordinator.address(), "--wait", "--quiet",
                              "--lights", "10", "--out", dir.Path("tiny.exr")});
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_TRUE(coordinator.process().running());
  EXPECT_TRUE(HealthServing(coordinator.address()));
}

TEST(FarmBadRpcs, WorkerCallsOutOfOrderGetPreciseCodesAndCannotFailAJob) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {"--lease-timeout", "0.5", "--max-attempts", "2"});
  auto channel = Channel(coordinator);
  auto stub = v1::WorkerService::NewStub(channel);
  RenderClient client = coordinator.Client();
  const std::string scene = dir.Write("tiny.pbrt", kTinyScene);

  auto register_worker = [&](const std::string& name) {
    v1::RegisterRequest req;
    req.set_name(name);
    req.set_protocol_version(kWorkerProtocolVersion);
    v1::RegisterResponse resp;
    EXPECT_TRUE(Unary([&](grpc::ClientContext* ctx) { return stub->Register(ctx, req, &resp); }).ok());
    return resp.worker_id();
  };
  auto lease = [&](const std::string& worker, v1::LeaseTaskResponse* resp) {
    v1::LeaseTaskRequest req;
    req.set_worker_id(worker);
    return Unary([&](grpc::ClientContext* ctx) { return stub->LeaseTask(ctx, req, resp); }).error_code();
  };
  auto heartbeat = [&](const std::string& worker, const std::string& lease_id, bool* keep_going = nullptr) {
    v1::HeartbeatRequest req;
    req.set_worker_id(worker);
    req.set_lease_id(lease_id);
    v1::HeartbeatResponse resp;
    const StatusCode code =
        Unary([&](grpc::ClientContext* ctx) { return stub->Heartbeat(ctx, req, &resp); }).error_code();
    if (keep_going) *keep_going = resp.keep_going();
    return code;
  };
  auto fail = [&](const std::string& worker, const std::string& lease_id) {
    v1::FailTaskRequest req;
    req.set_worker_id(worker);
    req.set_lease_id(lease_id);
    req.set_reason("forged");
    v1::FailTaskResponse resp;
    return Unary([&](grpc::ClientContext* ctx) { return stub->FailTask(ctx, req, &resp); }).error_code();
  };

  // Registration with a bad protocol version; leases for workers that never registered.
  {
    v1::RegisterRequest req;
    req.set_protocol_version(kWorkerProtocolVersion + 7);
    v1::RegisterResponse resp;
    EXPECT_EQ(Unary([&](grpc::ClientContext* ctx) { return stub->Register(ctx, req, &resp); }).error_code(),
              StatusCode::FAILED_PRECONDITION);
  }
  v1::LeaseTaskResponse none;
  EXPECT_EQ(lease("w-nobody", &none), StatusCode::NOT_FOUND);
  const std::string a = register_worker("a"), b = register_worker("b");
  EXPECT_EQ(lease(a, &none), StatusCode::OK);
  EXPECT_FALSE(none.has_task());

  // A job with one task (an 8×8 image is one slice), planned and waiting for a worker.
  const std::string job = client.Submit(client.UploadScene(scene, true), RenderSettings{}, 0, "");
  const v1::JobStatus running =
      WaitForJob(client, job, [](const v1::JobStatus& s) { return s.state() == v1::JOB_STATE_RUNNING; }, 60);
  ASSERT_EQ(running.state(), v1::JOB_STATE_RUNNING);
  const std::string forged = job + ".0.0.999999";

  // Calls on a lease before any was granted: the task was never leased.
  EXPECT_EQ(heartbeat(a, forged), StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(fail(a, forged), StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(Complete(*stub, {ResultChunk(a, forged, "junk", 4)}).error_code(), StatusCode::FAILED_PRECONDITION);
  // Malformed lease ids, leases of jobs and tasks that do not exist, unknown workers.
  for (const std::string& bad : {std::string(""), std::string("1.2"), std::string("a.b.c.d"), job + ".0.0.1x"}) {
    EXPECT_EQ(heartbeat(a, bad), StatusCode::INVALID_ARGUMENT) << bad;
    EXPECT_EQ(fail(a, bad), StatusCode::INVALID_ARGUMENT) << bad;
    EXPECT_EQ(Complete(*stub, {ResultChunk(a, bad, "junk", 4)}).error_code(), StatusCode::INVALID_ARGUMENT) << bad;
  }
  EXPECT_EQ(heartbeat(a, "987654.0.0.1"), StatusCode::NOT_FOUND);
  EXPECT_EQ(heartbeat(a, job + ".0.99.1"), StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(heartbeat(a, job + ".5.0.1"), StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(heartbeat("w-nobody", forged), StatusCode::NOT_FOUND);
  EXPECT_EQ(fail("w-nobody", forged), StatusCode::NOT_FOUND);
  EXPECT_EQ(Complete(*stub, {ResultChunk("w-nobody", forged, "junk", 4)}).error_code(), StatusCode::NOT_FOUND);

  // Worker a leases the task; a result for a lease beyond it was never granted either.
  v1::LeaseTaskResponse granted;
  ASSERT_EQ(lease(a, &granted), StatusCode::OK);
  ASSERT_TRUE(granted.has_task());
  const std::string lease_a = granted.lease_id();
  EXPECT_EQ(Complete(*stub, {ResultChunk(a, forged, "junk", 4)}).error_code(), StatusCode::FAILED_PRECONDITION);
  bool keep_going = false;
  EXPECT_EQ(heartbeat(a, lease_a, &keep_going), StatusCode::OK);
  EXPECT_TRUE(keep_going);
  // Another worker's heartbeat on a's lease: told to stop, a keeps it.
  EXPECT_EQ(heartbeat(b, lease_a, &keep_going), StatusCode::OK);
  EXPECT_FALSE(keep_going);
  // Result streams that lie about their size.
  EXPECT_EQ(Complete(*stub, {}).error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(Complete(*stub, {ResultChunk(a, lease_a, "abc", 2)}).error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(Complete(*stub, {ResultChunk(a, lease_a, "abc", 10)}).error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(Complete(*stub, {ResultChunk(a, lease_a, "abc", uint64_t(1) << 40)}).error_code(),
            StatusCode::RESOURCE_EXHAUSTED);

  // The lease expires (0.5 s without a heartbeat); b leases the task again; a's late heartbeat is
  // told to stop.
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  v1::LeaseTaskResponse regranted;
  ASSERT_EQ(lease(b, &regranted), StatusCode::OK);
  ASSERT_TRUE(regranted.has_task());
  EXPECT_NE(regranted.lease_id(), lease_a);
  EXPECT_EQ(heartbeat(a, lease_a, &keep_going), StatusCode::OK);
  EXPECT_FALSE(keep_going);
  EXPECT_EQ(fail(a, lease_a), StatusCode::OK);  // a no longer holds it: ignored

  // A valid result from b, then the same result again (a retry): accepted once, then a harmless
  // duplicate (OK, accepted = false); a's late result for the same task is a duplicate as well.
  const SubMatrixTask task = DeserializeTask(ByteView(
      reinterpret_cast<const uint8_t*>(regranted.task().data()), regranted.task().size()));
  TaskOutput output;
  output.row_sums.resize(task.rows.size());
  const Bytes bytes = SerializeTaskOutput(output);
  const std::string data(bytes.begin(), bytes.end());
  auto complete = [&](const std::string& worker, const std::string& lease_id, bool* accepted) {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    v1::CompleteTaskResponse resp;
    auto writer = stub->CompleteTask(&ctx, &resp);
    writer->Write(ResultChunk(worker, lease_id, data, data.size()));
    writer->WritesDone();
    const StatusCode code = writer->Finish().error_code();
    *accepted = resp.accepted();
    return code;
  };
  bool accepted = false;
  EXPECT_EQ(complete(b, regranted.lease_id(), &accepted), StatusCode::OK);
  EXPECT_TRUE(accepted);
  EXPECT_EQ(complete(b, regranted.lease_id(), &accepted), StatusCode::OK);
  EXPECT_FALSE(accepted);
  EXPECT_EQ(complete(a, lease_a, &accepted), StatusCode::OK);
  EXPECT_FALSE(accepted);
  const v1::JobStatus done = WaitForJob(client, job, [](const v1::JobStatus&) { return false; }, 60);
  EXPECT_EQ(done.state(), v1::JOB_STATE_DONE) << done.error();
  EXPECT_EQ(done.tasks_completed_total(), 1u);

  // A second job: forged leases and garbage results from registered workers that hold no lease
  // never count as the task's failures (with --max-attempts 2 two would fail the job).
  const std::string job2 = client.Submit(client.UploadScene(scene, true), RenderSettings{}, 0, "");
  ASSERT_EQ(WaitForJob(client, job2, [](const v1::JobStatus& s) { return s.state() == v1::JOB_STATE_RUNNING; }, 60)
                .state(),
            v1::JOB_STATE_RUNNING);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(Complete(*stub, {ResultChunk(b, job2 + ".0.0." + std::to_string(1000000 + i), "junk", 4)}).error_code(),
              StatusCode::FAILED_PRECONDITION);
    EXPECT_EQ(fail(b, job2 + ".0.0." + std::to_string(1000000 + i)), StatusCode::FAILED_PRECONDITION);
  }
  // b sends junk on the lease a holds: malformed (INVALID_ARGUMENT), but not a's failure.
  v1::LeaseTaskResponse held;
  ASSERT_EQ(lease(a, &held), StatusCode::OK);
  ASSERT_TRUE(held.has_task());
  for (int i = 0; i < 3; ++i)
    EXPECT_EQ(Complete(*stub, {ResultChunk(b, held.lease_id(), "junk", 4)}).error_code(),
              StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(client.GetJob(job2).state(), v1::JOB_STATE_RUNNING);
  // a's lease expires; a real worker finishes the job.
  auto worker = StartWorker(dir, coordinator.address());
  const v1::JobStatus done2 = WaitForJob(client, job2, [](const v1::JobStatus&) { return false; }, 120);
  EXPECT_EQ(done2.state(), v1::JOB_STATE_DONE) << done2.error();
  EXPECT_TRUE(coordinator.process().running());
  EXPECT_TRUE(HealthServing(coordinator.address()));
}

}  // namespace test_farm_bad_rpcs
}  // namespace lightfarm
