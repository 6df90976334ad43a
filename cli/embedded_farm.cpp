#include "cli/embedded_farm.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <filesystem>
#include <map>
#include <mutex>
#include <random>
#include <thread>

#include "common/farm/render_client.h"
#include "common/util/error.h"
#include "common/util/file.h"
#include "coordinator/services.h"
#include "worker/worker.h"

namespace lightfarm {

namespace fs = std::filesystem;

EmbeddedRender RenderOnEmbeddedFarm(const std::string& scene_path, const RenderSettings& settings,
                                    int workers,
                                    const std::function<void(const v1::JobStatus&)>& progress) {
  if (workers < 1) throw OptionError("--workers must be >= 1");
  // The farm logs a failing job as a warning; here the caller reports it (one line), so only
  // errors are logged while the embedded farm runs.
  struct LogLevel {
    spdlog::level::level_enum saved = spdlog::get_level();
    LogLevel() { spdlog::set_level(std::max(saved, spdlog::level::err)); }
    ~LogLevel() { spdlog::set_level(saved); }
  } quiet_farm_logs;
  std::random_device rd;
  const fs::path dir = fs::temp_directory_path() /
                       ("lightfarm-embedded-" + std::to_string(getpid()) + "-" + std::to_string(rd()));
  ScopedRemoveDir cleanup(dir);

  // Nothing crashes independently in one process: leases never need to expire, and the
  // coordinator's limits are the CLI's own.
  CoordinatorOptions copt;
  copt.state_dir = (dir / "state").string();
  copt.lease_timeout_s = 24 * 3600;
  copt.max_resolution = 1 << 20;
  copt.max_lights = ~uint64_t(0);
  copt.max_spp = 1 << 20;
  copt.max_blob_bytes = ~uint64_t(0) >> 2;
  copt.max_active_jobs = 1;
  // One render, no queue: a full disk fails it (nothing else would free the space) instead of
  // pausing it.
  copt.min_free_bytes = 0;
  copt.wait_for_space = false;
  std::mutex result_mu;
  std::map<std::string, Image> results;  // the latest result of each job
  copt.on_result = [&](const std::string& job, const Image& image) {
    std::lock_guard lock(result_mu);
    results[job] = image;
  };
  Coordinator coordinator(copt);
  coordinator.Start();
  ServerConfig scfg;
  scfg.rpc_threads = 2;
  FarmServer server(coordinator, scfg);

  std::vector<std::unique_ptr<Worker>> pool;
  std::vector<std::thread> threads;
  std::exception_ptr worker_error;
  std::mutex error_mu;
  for (int i = 0; i < workers; ++i) {
    WorkerOptions wopt;
    wopt.name = "embedded-" + std::to_string(i);
    wopt.cache_dir = (dir / ("worker-" + std::to_string(i))).string();
    wopt.idle_poll_s = 0.005;
    wopt.rpc_timeout_s = 3600;
    pool.push_back(std::make_unique<Worker>(server.InProcessChannel(), wopt));
    threads.emplace_back([&, w = pool.back().get()] {
      try {
        w->Run();
      } catch (...) {
        std::lock_guard lock(error_mu);
        worker_error = std::current_exception();
      }
    });
  }
  auto stop = [&] {
    for (auto& w : pool) w->Stop(true);
    for (std::thread& t : threads)
      if (t.joinable()) t.join();
    server.Shutdown(0);
    coordinator.Stop();
  };

  EmbeddedRender out;
  try {
    RenderClient client(server.InProcessChannel(), "", 3600);
    v1::SceneManifest manifest = client.UploadScene(scene_path, /*strict=*/true);
    std::string job;
    try {
      job = client.Submit(manifest, settings, 0, scene_path);
    } catch (const RpcError& e) {
      if (e.code() == grpc::StatusCode::INVALID_ARGUMENT || e.code() == grpc::StatusCode::RESOURCE_EXHAUSTED)
        throw OptionError(std::string(e.what()).substr(std::string(e.what()).find(": ") + 2));
      throw;
    }
    v1::JobStatus st = client.Watch(job, progress);
    if (st.state() != v1::JOB_STATE_DONE) throw std::runtime_error(st.error().empty() ? "job did not finish" : st.error());
    // The stats as a fetch serves them (the result blob verified on the way), the image as
    // the coordinator assembled it.
    out.stats = nlohmann::json::parse(coordinator.GetResult(job).stats_json);
    out.stats["scene"] = scene_path;
    out.stats["farm"]["workers"] = workers;
    out.stats["farm"]["mode"] = "embedded";
    std::lock_guard lock(result_mu);
    const auto found = results.find(job);
    if (found == results.end()) throw std::runtime_error("job " + job + " is done but handed over no image");
    out.image = std::move(found->second);
  } catch (...) {
    stop();
    throw;
  }
  stop();
  if (worker_error) std::rethrow_exception(worker_error);
  return out;
}

}  // namespace lightfarm
