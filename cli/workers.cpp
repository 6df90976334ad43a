// `lightfarm workers --server HOST:PORT [--json]`: the workers seen since the coordinator started,
// what each runs, its last call and its tasks.
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/farm_options.h"

namespace lightfarm::cli {

void AddWorkersCommand(CLI::App& app) {
  struct WorkersArgs {
    bool json = false;
    ServerArgs server;
  };
  auto args = std::make_shared<WorkersArgs>();
  CLI::App* cmd = app.add_subcommand("workers", "List the farm's workers");
  cmd->add_flag("--json", args->json, "One JSON object per worker");
  AddServerOptions(cmd, args->server);
  cmd->callback([args] {
    for (const v1::WorkerStatus& w : ConnectToCoordinator(args->server)->ListWorkers()) {
      if (args->json) {
        nlohmann::json j = {{"id", w.worker_id()},      {"name", w.name()},
                            {"version", w.version()},   {"threads", w.threads()},
                            {"lease_id", w.lease_id()}, {"job_id", w.job_id()},
                            {"last_seen_s", w.last_seen_s()}, {"alive", w.alive()},
                            {"tasks_done", w.tasks_done()},   {"tasks_failed", w.tasks_failed()}};
        std::cout << j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
        continue;
      }
      char seen[32];
      std::snprintf(seen, sizeof seen, "%.1f s ago", w.last_seen_s());
      std::cout << w.worker_id() << "  " << w.name() << "  v" << w.version() << "  " << w.threads() << " threads  "
                << (w.job_id().empty() ? std::string("idle") : "job " + w.job_id()) << "  " << seen
                << (w.alive() ? "" : " (lost)") << "  done " << w.tasks_done() << ", failed " << w.tasks_failed();
      if (w.blocked_jobs_size() > 0) {
        std::cout << "  kept off jobs";
        for (const std::string& b : w.blocked_jobs()) std::cout << " " << b;
      }
      std::cout << "\n";
    }
  });
}

}  // namespace lightfarm::cli
