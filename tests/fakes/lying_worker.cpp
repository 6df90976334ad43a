// A fake worker for the integrity tests (tests/integration/test_farm_verification.cpp): it speaks
// the worker protocol like lightfarm-worker but never renders. Each task it leases it answers
// with a result of the right shape and wrong numbers (--mode wrong), with NaN (--mode nan), or
// with a failure (--mode fail). Not installed.
//   lightfarm-test-lying-worker --coordinator HOST:PORT --mode wrong|nan|fail [--name NAME] [--hold N]
#include <grpcpp/grpcpp.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <thread>

#include "common/farm/farm_protocol.h"
#include "common/farm/rpc.h"
#include "common/render/serialize.h"
#include "lightfarm/v1/worker.grpc.pb.h"

namespace {

using namespace lightfarm;

grpc::Status Call(const std::function<grpc::Status(grpc::ClientContext*)>& fn) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  return fn(&ctx);
}

int Run(const std::string& address, const std::string& mode, const std::string& name, int hold) {
  std::vector<std::string> held;
  ChannelOptions channel;
  channel.address = address;
  auto stub = v1::WorkerService::NewStub(MakeChannel(channel));
  v1::RegisterRequest reg;
  reg.set_name(name);
  reg.set_protocol_version(kWorkerProtocolVersion);
  reg.set_software_version(LIGHTFARM_VERSION);
  v1::RegisterResponse registered;
  for (;;) {
    if (Call([&](auto* ctx) { return stub->Register(ctx, reg, &registered); }).ok()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::cout << "registered as " << registered.worker_id() << std::endl;
  for (;;) {
    v1::LeaseTaskRequest req;
    req.set_worker_id(registered.worker_id());
    v1::LeaseTaskResponse lease;
    const grpc::Status st = Call([&](auto* ctx) { return stub->LeaseTask(ctx, req, &lease); });
    if (!st.ok()) std::cout << "lease: " << st.error_message() << std::endl;
    if (!st.ok() || !lease.has_task()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      continue;
    }
    if (mode == "fail") {
      // Holds `hold` leases, then fails them all: distinct tasks, so the worker reaches the
      // farm's per-job limit before any task reaches its own.
      held.push_back(lease.lease_id());
      if (held.size() < size_t(hold)) continue;
      for (const std::string& id : held) {
        v1::FailTaskRequest f;
        f.set_worker_id(registered.worker_id());
        f.set_lease_id(id);
        f.set_reason("injected failure");
        v1::FailTaskResponse resp;
        Call([&](auto* ctx) { return stub->FailTask(ctx, f, &resp); });
      }
      held.clear();
      continue;
    }
    const SubMatrixTask task = DeserializeTask(
        ByteView(reinterpret_cast<const uint8_t*>(lease.task().data()), lease.task().size()));
    TaskOutput out;
    const double v = mode == "nan" ? std::numeric_limits<double>::quiet_NaN() : 0.37;  // plausible, wrong
    RGBAccum wrong;
    wrong.r = wrong.g = wrong.b = v;
    out.row_sums.assign(task.rows.size(), wrong);
    const Bytes bytes = SerializeTaskOutput(out);
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    v1::CompleteTaskResponse resp;
    auto writer = stub->CompleteTask(&ctx, &resp);
    const grpc::Status done = WriteChunked(*writer, bytes.data(), bytes.size(), [&](v1::TaskResultChunk& chunk) {
      chunk.set_worker_id(registered.worker_id());
      chunk.set_lease_id(lease.lease_id());
      chunk.set_total_size(bytes.size());
    });
    std::cout << "delivered " << lease.lease_id() << ": " << (done.ok() ? "accepted" : done.error_message())
              << std::endl;
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"lightfarm-test-lying-worker: a worker that lies (tests only)"};
  std::string address, mode = "wrong", name = "liar";
  app.add_option("--coordinator", address)->required();
  app.add_option("--mode", mode)->check(CLI::IsMember({"wrong", "nan", "fail"}));
  int hold = 1;
  app.add_option("--name", name);
  app.add_option("--hold", hold, "--mode fail: leases held before failing them")->check(CLI::Range(1, 1000));
  CLI11_PARSE(app, argc, argv);
  return Run(address, mode, name, hold);
}
