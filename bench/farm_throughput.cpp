// Coordinator lease throughput: a real coordinator and gRPC server on loopback, a job of many
// one-row tasks, and W simulated workers doing no work, multiplexed over C client threads (each
// thread takes its workers in turn): Register, then LeaseTask → CompleteTask (a valid all-zero
// result) until the job is done. What is measured is the coordinator's side of a task's life
// (lease, SQLite attempt record, result validation and blob write, completion) through the
// network stack, not rendering: leases per second, the LeaseTask latency (p50, p99), the
// planning time of the job, and the process's peak resident memory (coordinator and clients).
//
//   lightfarm_bench_farm [--tasks N] [--workers W] [--clients C] [--repeats K] [--json]
//
// With --plan SCENE it measures instead what the coordinator does for a large reference: plans
// it (BuildPlan as the coordinator runs it: lights, receivers, slices) with the time and the
// process's peak memory, runs --sample-tasks of its tasks here on one thread, and predicts the
// cluster time per worker-core from their mean (tasks × mean task time).
//
//   lightfarm_bench_farm --plan SCENE [--method brute] [--lights N] [--resolution WxH] [--json]
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
#include <optional>
#include <iostream>
#include <random>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include <tbb/global_control.h>

#include "common/farm/render_client.h"
#include "common/render/stage_engine.h"
#include "common/render/serialize.h"
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
  double seconds = 0, planning_seconds = 0;
  std::vector<double> lease_latency_s;  // every LeaseTask that returned a task
};

// The process's peak resident set (VmHWM), in MiB.
double PeakRssMiB() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0;
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const size_t at = size_t(q * double(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(at), v.end());
  return v[at];
}

RunResult RunOnce(const fs::path& dir, int side, int workers, int clients, bool piggyback) {
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
  const auto submitted = std::chrono::steady_clock::now();
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

  const double planning_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - submitted).count();
  std::atomic<size_t> completed{0};
  std::atomic<bool> done{false};
  std::vector<std::vector<double>> latencies(static_cast<size_t>(clients));
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&, c] {
      auto stub = v1::WorkerService::NewStub(grpc::CreateCustomChannel(
          co.address, grpc::InsecureChannelCredentials(), FarmChannelArguments()));
      auto deadline = [](grpc::ClientContext* ctx) {
        ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
      };
      // This thread's simulated workers: c, c + clients, c + 2·clients, ...
      std::vector<std::string> ids;
      for (int w = c; w < workers; w += clients) {
        v1::RegisterRequest reg;
        reg.set_name("bench-" + std::to_string(w));
        reg.set_protocol_version(kWorkerProtocolVersion);
        reg.set_software_version("bench");
        v1::RegisterResponse who;
        grpc::ClientContext ctx;
        deadline(&ctx);
        if (!stub->Register(&ctx, reg, &who).ok()) throw std::runtime_error("register failed");
        ids.push_back(who.worker_id());
      }
      size_t turn = 0;
      // A worker's next lease, when it came with its last completion (lease_next).
      std::vector<std::optional<v1::LeaseTaskResponse>> next(ids.size());
      while (!done && !ids.empty()) {
        const size_t w = turn++ % ids.size();
        const std::string& worker_id = ids[w];
        v1::LeaseTaskResponse lease;
        if (next[w]) {
          lease = std::move(*next[w]);
          next[w].reset();
        } else {
          v1::LeaseTaskRequest req;
          req.set_worker_id(worker_id);
          grpc::ClientContext ctx;
          deadline(&ctx);
          const auto asked = std::chrono::steady_clock::now();
          if (!stub->LeaseTask(&ctx, req, &lease).ok()) throw std::runtime_error("lease failed");
          if (lease.has_task())
            latencies[size_t(c)].push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - asked).count());
        }
        if (!lease.has_task()) {
          std::this_thread::sleep_for(std::chrono::microseconds(200));
          continue;
        }
        const SubMatrixTask task = DeserializeTask(
            ByteView(reinterpret_cast<const uint8_t*>(lease.task().data()), lease.task().size()));
        TaskOutput out;
        out.row_sums.resize(task.rows.size());
        const Bytes bytes = SerializeTaskOutput(out);
        const auto sent = std::chrono::steady_clock::now();
        grpc::ClientContext cctx;
        deadline(&cctx);
        v1::CompleteTaskResponse resp;
        auto writer = stub->CompleteTask(&cctx, &resp);
        v1::TaskResultChunk chunk;
        chunk.set_worker_id(worker_id);
        chunk.set_lease_next(piggyback);
        chunk.set_lease_id(lease.lease_id());
        chunk.set_total_size(bytes.size());
        chunk.set_data(reinterpret_cast<const char*>(bytes.data()), bytes.size());
        writer->Write(chunk);
        writer->WritesDone();
        if (!writer->Finish().ok()) throw std::runtime_error("complete failed");
        if (resp.has_next() && resp.next().has_task()) {
          // The completion's call delivered the next lease: its latency is this call's.
          latencies[size_t(c)].push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count());
          next[w] = resp.next();
        }
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
  RunResult result{completed.load(), seconds, planning_seconds, {}};
  for (const auto& l : latencies) result.lease_latency_s.insert(result.lease_latency_s.end(), l.begin(), l.end());
  return result;
}

// Plans a reference as the coordinator would and times a sample of its tasks on one thread.
nlohmann::json PlanScale(const std::string& scene, const RenderSettings& settings, int sample_tasks) {
  const auto t0 = std::chrono::steady_clock::now();
  PhaseTimes times;
  const Plan plan = BuildPlan(scene, settings, &times);
  const double plan_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double plan_rss = PeakRssMiB();
  const StageEngine engine(plan);
  nlohmann::json out = {{"scene", scene},
                        {"method", plan.method->name()},
                        {"lights", plan.lights->lights.size()},
                        {"receivers", plan.receivers->points.size()},
                        {"resolution", std::to_string(plan.receivers->width) + "x" + std::to_string(plan.receivers->height)},
                        {"planning_s", plan_s},
                        {"planning_peak_rss_mib", plan_rss},
                        {"stages", engine.stage_count()}};
  nlohmann::json phases = nlohmann::json::object();
  for (const auto& [name, s] : times.phases) phases[name] = s;
  out["planning_phases_s"] = phases;
  if (engine.stage_count() != 1) return out;  // multi-stage methods: the task times need the stages before
  const std::vector<SubMatrixTask> tasks = engine.Tasks(0, {});
  out["tasks"] = tasks.size();
  // Evenly spread tasks, on one thread (a worker-core).
  tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  double sum = 0;
  size_t rows = 0;
  const int n = std::min<int>(sample_tasks, int(tasks.size()));
  for (int k = 0; k < n; ++k) {
    const SubMatrixTask& task = tasks[size_t(k) * tasks.size() / size_t(n)];
    const auto t = std::chrono::steady_clock::now();
    RunGatherTask(*plan.method, plan.context(), task, {});
    sum += std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
    rows += task.rows.size();
  }
  const double per_task = sum / double(std::max(1, n));
  out["sampled_tasks"] = n;
  out["sampled_rows"] = rows;
  out["mean_task_s"] = per_task;
  out["predicted_worker_core_hours"] = per_task * double(tasks.size()) / 3600.0;
  out["peak_rss_mib"] = PeakRssMiB();
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Coordinator lease throughput with no-op tasks over loopback gRPC"};
  int tasks = 1024, workers = 0, clients = 4, repeats = 3;
  bool separate_lease = false;
  bool json = false;
  app.add_option("--tasks", tasks, "Tasks per job (rounded to a square film)")->check(CLI::Range(16, 1 << 20));
  app.add_option("--workers", workers, "Simulated workers (default: one per client)")->check(CLI::Range(1, 100000));
  app.add_option("--clients", clients, "Client threads the workers are multiplexed over")->check(CLI::Range(1, 256));
  app.add_option("--repeats", repeats, "Jobs to run (the median is reported)")->check(CLI::Range(1, 100));
  app.add_flag("--json", json, "Print one JSON object");
  app.add_flag("--separate-lease", separate_lease,
               "Lease with LeaseTask only (as workers before lease_next did), not with the completion");
  std::string plan_scene, method = "brute", resolution;
  size_t lights = 1000000;
  int sample_tasks = 2;
  app.add_option("--plan", plan_scene, "Plan this scene as a large reference instead (see the top of the file)");
  app.add_option("--method", method, "--plan: gather method");
  app.add_option("--lights", lights, "--plan: virtual lights");
  app.add_option("--resolution", resolution, "--plan: WxH");
  app.add_option("--sample-tasks", sample_tasks, "--plan: tasks to time")->check(CLI::Range(1, 1000));
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);
  if (!plan_scene.empty()) {
    RenderSettings settings;
    settings.method = method;
    settings.lights = lights;
    if (!resolution.empty() && std::sscanf(resolution.c_str(), "%dx%d", &settings.width, &settings.height) != 2) {
      std::cerr << "lightfarm_bench_farm: --resolution expects WxH\n";
      return 2;
    }
    try {
      const nlohmann::json out = PlanScale(plan_scene, settings, sample_tasks);
      std::cout << (json ? out.dump() : out.dump(2)) << "\n";
    } catch (const std::exception& e) {
      std::cerr << "lightfarm_bench_farm: " << e.what() << "\n";
      return 1;
    }
    return 0;
  }
  const int side = std::max(4, int(std::lround(std::sqrt(double(tasks)))));
  if (workers == 0) workers = clients;
  std::vector<double> rates, p50, p99, planning;
  try {
    for (int r = 0; r < repeats; ++r) {
      const fs::path dir = fs::temp_directory_path() /
                           ("lightfarm-bench-farm-" + std::to_string(getpid()) + "-" + std::to_string(r));
      fs::create_directories(dir);
      const RunResult res = RunOnce(dir, side, workers, clients, !separate_lease);
      fs::remove_all(dir);
      rates.push_back(double(res.tasks) / res.seconds);
      p50.push_back(Percentile(res.lease_latency_s, 0.5) * 1e3);
      p99.push_back(Percentile(res.lease_latency_s, 0.99) * 1e3);
      planning.push_back(res.planning_seconds);
      if (!json)
        std::cout << "repeat " << r << ": " << res.tasks << " tasks in " << res.seconds << " s = " << rates.back()
                  << " leases/s, lease latency p50 " << p50.back() << " ms p99 " << p99.back()
                  << " ms, planning " << planning.back() << " s\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "lightfarm_bench_farm: " << e.what() << "\n";
    return 1;
  }
  std::vector<double> sorted = rates;
  std::sort(sorted.begin(), sorted.end());
  const double median = sorted[sorted.size() / 2];
  if (json) {
    std::cout << nlohmann::json{{"film", side},
                                {"tasks", side * side},
                                {"workers", workers},
                                {"clients", clients},
                                {"lease_with_completion", !separate_lease},
                                {"repeats", rates},
                                {"median_leases_per_s", median},
                                {"lease_p50_ms", p50},
                                {"lease_p99_ms", p99},
                                {"planning_s", planning},
                                {"peak_rss_mib", PeakRssMiB()}}
                     .dump()
              << "\n";
  } else {
    std::cout << "median: " << median << " leases/s (" << clients << " clients)\n";
  }
  return 0;
}
