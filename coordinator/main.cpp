// `lightfarm-coordinator --listen HOST:PORT --state-dir DIR [--token-file F] [--tls-cert F
// --tls-key F] [--metrics-listen HOST:PORT] [--http-listen [HOST:]PORT] [limits]`: the farm's job service. SIGTERM/SIGINT
// drain it (health NOT_SERVING, in-flight RPCs finish); unfinished jobs resume at the next start.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>
#include <thread>

#include "common/image/image_io.h"
#include "common/farm/program.h"
#include "common/farm/rpc.h"
#include "coordinator/services.h"

int main(int argc, char** argv) {
  lightfarm::SetFloatingPointMode();
  lightfarm::LogToStderr("coordinator");

  CLI::App app{"lightfarm-coordinator: the lightfarm render-farm service"};
  lightfarm::CoordinatorOptions opt;
  lightfarm::ServerConfig server;
  std::string token_file, log_level = "info";
  double max_blob_mb = 1024, drain_s = 10;
  const CLI::Validator listen_address = lightfarm::HostPort(true);
  app.add_option("--listen", server.listen, "gRPC HOST:PORT (port 0: pick one, printed)")
      ->required()
      ->check(listen_address);
  app.add_option("--state-dir", opt.state_dir, "SQLite state and blob store")->required();
  app.add_option("--token-file", token_file, "Bearer token required on every RPC");
  app.add_option("--tls-cert", server.tls_cert, "PEM certificate chain (TLS)");
  app.add_option("--tls-key", server.tls_key, "PEM private key (TLS)");
  app.add_option("--metrics-listen", server.metrics_listen, "HOST:PORT serving Prometheus /metrics")
      ->check(listen_address);
  app.add_option("--http-listen", server.http_listen,
                 "[HOST:]PORT serving the dashboard at /, JSON at /api/v1/ and /metrics (PORT alone: 127.0.0.1)");
  app.add_flag("--http-allow-open", server.http_allow_open,
               "Serve the dashboard on a non-loopback host without --token-file (anyone reaching it can cancel jobs)");
  app.add_option("--bench-dir", server.bench_dir,
                 "Directory of `lightfarm bench --out-dir` results whose error-versus-time plots the dashboard shows");
  app.add_option("--lease-timeout", opt.lease_timeout_s, "Seconds a lease lives without a heartbeat")
      ->check(lightfarm::FiniteRange(0.05, 86400.0));
  app.add_option("--max-attempts", opt.max_attempts, "Failed attempts before a task (and its job) fails")
      ->check(CLI::Range(1, 100));
  app.add_option("--max-blob-mb", max_blob_mb, "Largest blob accepted, MiB")->check(lightfarm::FiniteRange(0.001, 1e9));
  app.add_option("--max-resolution", opt.max_resolution, "Largest image side in pixels")->check(CLI::Range(1, 1 << 20));
  app.add_option("--max-lights", opt.max_lights, "Most virtual lights a job may request")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 40));
  app.add_option("--max-spp", opt.max_spp, "Most samples per pixel a job may request")->check(CLI::Range(1, 1 << 20));
  app.add_option("--max-active-jobs", opt.max_active_jobs, "Jobs planned or running at once")->check(CLI::Range(1, 10000));
  app.add_option("--max-queued-jobs", opt.max_queued_jobs, "Unfinished jobs accepted")->check(CLI::Range(1, 1000000));
  app.add_option("--planner-threads", opt.planner_threads, "Threads planning and combining jobs")->check(CLI::Range(1, 64));
  double min_free_mb = 100;
  app.add_option("--min-free-mb", min_free_mb,
                 "Free space under --state-dir below which new jobs, uploads and leases wait (MiB)")
      ->check(lightfarm::FiniteRange(0.0, 1e9));
  app.add_flag("--fresh-state", opt.fresh_state,
               "Start an empty farm even though --state-dir holds blobs and its database is missing or empty");
  app.add_option("--verify-share", opt.verify_share,
                 "Share of tasks run on a second worker and compared bit for bit (0..1; a job's --verify: all)")
      ->check(lightfarm::FiniteRange(0.0, 1.0));
  app.add_option("--retain-finished-s", opt.retain_finished_s,
                 "Delete finished jobs this many seconds after they ended (0: keep until `lightfarm delete`)")
      ->check(lightfarm::FiniteRange(0.0, 1e12));
  app.add_option("--gc-interval-s", opt.gc_interval_s, "Seconds between collections of unused blobs")
      ->check(lightfarm::FiniteRange(0.1, 1e9));
  app.add_option("--gc-grace-s", opt.gc_grace_s,
                 "A blob written or asked for within this many seconds is never collected (an upload before its submit)")
      ->check(lightfarm::FiniteRange(0.0, 1e9));
  app.add_option("--scrub-mb-per-s", opt.scrub_mb_per_s,
                 "Rate at which stored blobs are re-hashed in the background, MiB/s (0: off)")
      ->check(lightfarm::FiniteRange(0.0, 1e6));
  app.add_option("--rpc-threads", server.rpc_threads, "Threads serving RPCs")->check(CLI::Range(1, 256));
  app.add_option("--drain-seconds", drain_s, "Grace period for in-flight RPCs on SIGTERM")
      ->check(lightfarm::FiniteRange(0.0, 86400.0));
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error")->check(lightfarm::LogLevel());
  if (auto exit_code = lightfarm::ParseCommandLine(app, argc, argv, "lightfarm-coordinator")) return *exit_code;
  spdlog::set_level(spdlog::level::from_str(log_level));
  return lightfarm::RunProgram("lightfarm-coordinator", [&] {
    opt.max_blob_bytes = uint64_t(max_blob_mb * 1024.0 * 1024.0);
    opt.min_free_bytes = uint64_t(min_free_mb * 1024.0 * 1024.0);
    server.token = lightfarm::ReadTokenFile(token_file);
    lightfarm::RequireImageIo();  // every job ends in an EXR: fail now, not at the first job's end
    lightfarm::Coordinator coordinator(opt);
    coordinator.Start();
    lightfarm::FarmServer farm(coordinator, server);
    lightfarm::CatchStopSignals();
    // The port lines are how scripts learn a picked port (--listen HOST:0); written in one call,
    // so a reader that sees the first sees the second.
    std::string ports = "listening on port " + std::to_string(farm.port()) + "\n";
    if (farm.http_port()) ports += "dashboard on port " + std::to_string(farm.http_port()) + "\n";
    std::cout << ports << std::flush;
    spdlog::info("listening on {} (port {}), state in {}", server.listen, farm.port(), opt.state_dir);
    while (lightfarm::StopSignals() == 0) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    spdlog::info("draining");
    farm.Shutdown(drain_s);
    coordinator.Stop();
    spdlog::info("stopped");
    return 0;
  });
}
