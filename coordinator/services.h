// The coordinator's gRPC services (callback API) and the server around them: RenderService for
// clients, WorkerService for workers, grpc.health.v1, reflection, Prometheus metrics over HTTP.
// Reactions never block: each request is handed to a thread pool, which finishes the reactor.
// This is the boundary where FarmError and every other exception become a grpc::Status.
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>
#include <thread>

#include "common/farm/rpc.h"
#include "coordinator/coordinator.h"
#include "coordinator/dashboard.h"
#include "lightfarm/v1/render.grpc.pb.h"
#include "lightfarm/v1/worker.grpc.pb.h"

namespace lightfarm {

struct ServerConfig {
  std::string listen;          // host:port; empty: in-process channels only (embedded mode)
  std::string token;           // bearer token required on every RPC; empty: no auth
  std::string tls_cert, tls_key;  // PEM files; both empty: plaintext
  std::string metrics_listen;  // host:port for GET /metrics alone; empty: off
  std::string http_listen;     // [host:]port for the dashboard, /api/v1/ and /metrics; empty: off
  bool http_allow_open = false;  // serve the dashboard without a token on a non-loopback host
  std::string bench_dir;       // bench results whose plots the dashboard shows
  int rpc_threads = 4;
};

class WatchHub;

class FarmServer {
 public:
  FarmServer(Coordinator& coordinator, const ServerConfig& config);
  ~FarmServer();
  FarmServer(const FarmServer&) = delete;
  FarmServer& operator=(const FarmServer&) = delete;

  // A channel to this server inside this process (embedded mode, tests).
  std::shared_ptr<grpc::Channel> InProcessChannel();
  int port() const { return port_; }
  int http_port() const { return http_ ? http_->port() : 0; }
  // Graceful drain: health NOT_SERVING, refuse new jobs and leases, finish in-flight RPCs
  // (cancelling what is left after `grace_seconds`), stop the pool.
  void Shutdown(double grace_seconds);

 private:
  class RenderServiceImpl;
  class WorkerServiceImpl;
  Coordinator& coordinator_;
  std::unique_ptr<ThreadPool> pool_;
  std::unique_ptr<WatchHub> watch_hub_;
  std::unique_ptr<RenderServiceImpl> render_service_;
  std::unique_ptr<WorkerServiceImpl> worker_service_;
  std::unique_ptr<grpc::Server> server_;
  std::unique_ptr<HttpServer> metrics_, http_;
  int port_ = 0;
  bool shut_down_ = false;
};

}  // namespace lightfarm
