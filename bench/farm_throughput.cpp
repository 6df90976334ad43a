// Coordinator lease throughput: a real coordinator and gRPC server on
// loopback, a job of many one-row tasks, and N client threads that act as workers doing no work:
// Register, then LeaseTask → CompleteTask (a valid all-zero result) until the job is done. What
// is measured is the coordinator's side of a task's life (lease, SQLite attempt record, result
// validation and blob write, completion) through the network stack, not rendering.
//
//   lightfarm_bench_farm [--tasks N] [--clients C] [--repeats K] [--json]
//
// Prints leases/s per repeat and the median; --json prints one JSON object instead.
#include <CLI/CLI.hpp>
#include <grpcpp/grpcpp.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/farm/render_client.h"
#include "common/farm/serialize.h"
#include "coordinator/coordinator.h"
#include "coordinator/services.h"
#include "lightfarm/v1/worker.grpc.pb.h"

namespace fs = std::filesystem;
using namespace lightfarm;

namespace {

// A square film of `side`² pixels filled by a quad, one point light: planning is instant and every
// task is one receiver row.
std::string TinyScene(int side) {
  return "Film \"rgb\" \"integer xresolution\" [" + std::to_string(side) + "] \"integer yresolution\" [" +
         std::to_string(side) +
         "]\nLookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\nWorldBegin\n"
         "LightSource \"point\" \"rgb I\" [5 5 5] \"point3 from\" [0 0 3]\n"
         "Shape \"trianglemesh\" \"point3 P\" [-9 -9 0 9 -9 0 9 9 0 -9 9 0] \"integer indices\" [0 1 2 0 2 3]\n";
}

struct RunResult {
  size_t tasks = 0;
  double seconds = 0;
};

RunResult RunOnce(const fs::path& dir, int side, int clients) {
  CoordinatorOptions copt;
  copt.state_dir = (dir / "state").string();
  copt.lease_timeout_s = 600;
  copt.max_active_jobs = 1;
  Coordinator coordinator(copt);
  coordinator.Start();
  ServerConfig scfg;
  scfg.listen = "127.0.0.1:0";
  scfg.rpc_threads = 4;
  FarmServer server(coordinator, scfg);
  ChannelOptions co;
  co.address = "127.0.0.1:" + std::to_string(server.port());

  std::ofstream(dir / "scene.pbrt") << TinyScene(side);
  RenderClient client(MakeChannel(co), "", 600);
  RenderSettings settings;
  settings.method = "brute";
  settings.lights = 1;
  settings.params = {"rows_per_slice=1"};
  const std::string job = client.Submit(client.UploadScene((dir / "scene.pbrt").string(), true), settings, 0, "bench");
  // Planning runs on the coordinator: wait until the tasks are queued.
  size_t total = 0;
  for (;;) {
    v1::JobStatus st = client.GetJob(job);
    if (st.state() == v1::JOB_STATE_RUNNING && st.tasks_total() > 0) {
      total = st.tasks_total();  // one per receiver: pixels that miss the quad have none
      break;
    }
    if (st.state() != v1::JOB_STATE_QUEUED && st.state() != v1::JOB_STATE_PLANNING)
      throw std::runtime_error("job did not start: " + st.error());
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }

  std::atomic<size_t> completed{0};
  std::atomic<bool> done{false};
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&, c] {
      auto stub = v1::WorkerService::NewStub(grpc::CreateCustomChannel(
          co.address, grpc::InsecureChannelCredentials(), FarmChannelArguments()));
      auto deadline = [](grpc::ClientContext* ctx) {
        ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
      };
      v1::RegisterRequest reg;
      reg.set_name("bench-" + std::to_string(c));
      reg.set_protocol_version(kWorkerProtocolVersion);
      reg.set_software_version("bench");
      v1::RegisterResponse who;
      {
        grpc::ClientContext ctx;
        deadline(&ctx);
        if (!stub->Register(&ctx, reg, &who).ok()) throw std::runtime_error("register failed");
      }
      while (!done) {
        v1::LeaseTaskRequest req;
        req.set_worker_id(who.worker_id());
        v1::LeaseTaskResponse lease;
        grpc::ClientContext ctx;
        deadline(&ctx);
        if (!stub->LeaseTask(&ctx, req, &lease).ok()) throw std::runtime_error("lease failed");
        if (!lease.has_task()) {
          std::this_thread::sleep_for(std::chrono::microseconds(200));
          continue;
        }
        const SubMatrixTask task = DeserializeTask(
            ByteView(reinterpret_cast<const uint8_t*>(lease.task().data()), lease.task().size()));
        TaskOutput out;
        out.row_sums.resize(task.rows.size());
        const Bytes bytes = SerializeTaskOutput(out);
        grpc::ClientContext cctx;
        deadline(&cctx);
        v1::CompleteTaskResponse resp;
        auto writer = stub->CompleteTask(&cctx, &resp);
        v1::TaskResultChunk chunk;
        chunk.set_worker_id(who.worker_id());
        chunk.set_lease_id(lease.lease_id());
        chunk.set_total_size(bytes.size());
        chunk.set_data(reinterpret_cast<const char*>(bytes.data()), bytes.size());
        writer->Write(chunk);
        writer->WritesDone();
        if (!writer->Finish().ok()) throw std::runtime_error("complete failed");
        ++completed;
      }
    });
  }
  // The job is done when the coordinator has every completion (it then assembles the film).
  while (completed < total) std::this_thread::sleep_for(std::chrono::microseconds(200));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  done = true;
  for (std::thread& t : threads) t.join();
  v1::JobStatus st;
  do {
    st = client.GetJob(job);
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  } while (st.state() == v1::JOB_STATE_RUNNING);
  if (st.state() != v1::JOB_STATE_DONE) throw std::runtime_error("job ended " + st.error());
  server.Shutdown(0);
  coordinator.Stop();
  return RunResult{completed.load(), seconds};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Coordinator lease throughput with no-op tasks over loopback gRPC"};
  int tasks = 1024, clients = 4, repeats = 3;
  bool json = false;
  app.add_option("--tasks", tasks, "Tasks per job (rounded to a square film)")->check(CLI::Range(16, 1 << 20));
  app.add_option("--clients", clients, "Concurrent no-op workers")->check(CLI::Range(1, 256));
  app.add_option("--repeats", repeats, "Jobs to run (the median is reported)")->check(CLI::Range(1, 100));
  app.add_flag("--json", json, "Print one JSON object");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);
  const int side = std::max(4, int(std::lround(std::sqrt(double(tasks)))));
  std::vector<double> rates;
  try {
    for (int r = 0; r < repeats; ++r) {
      const fs::path dir = fs::temp_directory_path() /
                           ("lightfarm-bench-farm-" + std::to_string(getpid()) + "-" + std::to_string(r));
      fs::create_directories(dir);
      const RunResult res = RunOnce(dir, side, clients);
      fs::remove_all(dir);
      rates.push_back(double(res.tasks) / res.seconds);
      if (!json) std::cout << "repeat " << r << ": " << res.tasks << " tasks in " << res.seconds << " s = "
                           << rates.back() << " leases/s\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "lightfarm_bench_farm: " << e.what() << "\n";
    return 1;
  }
  std::vector<double> sorted = rates;
  std::sort(sorted.begin(), sorted.end());
  const double median = sorted[sorted.size() / 2];
  if (json) {
    std::cout << nlohmann::json{{"film", side}, {"clients", clients}, {"repeats", rates},
                                {"median_leases_per_s", median}}
                     .dump()
              << "\n";
  } else {
    std::cout << "median: " << median << " leases/s (" << clients << " clients)\n";
  }
  return 0;
}
