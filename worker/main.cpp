// `lightfarm-worker --coordinator HOST:PORT [--threads N] [--cache-dir DIR] [--token-file F]`:
// pulls tasks until SIGTERM/SIGINT (first signal: finish the current task; second: hand it back).
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <iostream>
#include <thread>

#include "common/farm/program.h"
#include "common/farm/rpc.h"
#include "worker/worker.h"

int main(int argc, char** argv) {
  lightfarm::SetFloatingPointMode();
  lightfarm::LogToStderr("worker");

  CLI::App app{"lightfarm-worker: runs render tasks leased from a lightfarm coordinator"};
  lightfarm::ChannelOptions channel;
  lightfarm::WorkerOptions options;
  std::string token_file, log_level = "info";
  int threads = 0;
  double cache_gb = 4;
  app.add_option("--coordinator", channel.address, "Coordinator HOST:PORT")
      ->required()
      ->check(lightfarm::HostPort(false));
  app.add_option("--threads", threads, "Threads for tasks (0 = all cores)")->check(CLI::Range(0, 4096));
  app.add_option("--cache-dir", options.cache_dir, "Blob cache directory (default: temporary)");
  app.add_option("--cache-gb", cache_gb, "Blob cache bound in GiB")->check(lightfarm::FiniteRange(0.001, 1e6));
  app.add_option("--token-file", token_file, "File holding the bearer token");
  app.add_flag("--tls", channel.tls, "Connect with TLS");
  app.add_option("--tls-ca", channel.tls_ca, "PEM root certificates for TLS (default: system)");
  app.add_option("--name", options.name, "Worker name shown by the coordinator");
  app.add_option("--poll-interval", options.idle_poll_s, "Seconds between polls while idle")
      ->check(lightfarm::FiniteRange(0.001, 60.0));
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error")
      ->check(lightfarm::LogLevel());
  // Hidden: lets tests pretend to be a worker of another protocol version.
  app.add_option("--protocol-version", options.protocol_version)->group("");
  if (auto exit_code = lightfarm::ParseCommandLine(app, argc, argv, "lightfarm-worker")) return *exit_code;
  spdlog::set_level(spdlog::level::from_str(log_level));

  return lightfarm::RunProgram("lightfarm-worker", [&] {
    options.token = lightfarm::ReadTokenFile(token_file);
    options.threads = threads;
    options.cache_bytes = uint64_t(cache_gb * double(1ull << 30));
    std::unique_ptr<tbb::global_control> limit;
    if (threads > 0)
      limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));
    lightfarm::Worker worker(lightfarm::MakeChannel(channel), options);
    lightfarm::CatchStopSignals();
    // A watcher thread turns signals into Stop() calls: the first drains, the second hands back.
    std::atomic<bool> done{false};
    std::thread watcher([&] {
      int seen = 0;
      while (!done) {
        if (lightfarm::StopSignals() > seen) {
          seen = lightfarm::StopSignals();
          spdlog::info(seen == 1 ? "draining: finishing the current task" : "handing the current task back");
          worker.Stop(seen > 1);
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
    });
    int rc = 0;
    try {
      worker.Run();
    } catch (const lightfarm::WorkerRefused& e) {
      std::cerr << "lightfarm-worker: " << e.what() << "\n";
      rc = 3;
    }
    done = true;
    watcher.join();
    spdlog::info("stopped after {} tasks", worker.tasks_done());
    return rc;
  });
}
