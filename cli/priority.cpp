// `lightfarm priority JOB N --server HOST:PORT`: changes a queued or running job's priority
// (higher leases first).
#include <iostream>

#include "cli/commands.h"
#include "cli/farm_options.h"

namespace lightfarm::cli {

void AddPriorityCommand(CLI::App& app) {
  struct PriorityArgs {
    std::string job;
    int priority = 0;
    ServerArgs server;
  };
  auto args = std::make_shared<PriorityArgs>();
  CLI::App* cmd = app.add_subcommand("priority", "Change a farm job's priority");
  cmd->add_option("job", args->job, "Job id")->required();
  cmd->add_option("priority", args->priority, "New priority (higher runs first)")->required();
  AddServerOptions(cmd, args->server);
  cmd->callback([args] {
    std::cout << DescribeJob(ConnectToCoordinator(args->server)->SetPriority(args->job, args->priority)) << "\n";
  });
}

}  // namespace lightfarm::cli
