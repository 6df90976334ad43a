// `lightfarm cancel JOB --server HOST:PORT`: stops a job; its queued tasks are dropped.
#include <iostream>

#include "cli/commands.h"
#include "cli/farm_options.h"

namespace lightfarm::cli {

void AddCancelCommand(CLI::App& app) {
  struct CancelArgs {
    std::string job;
    ServerArgs server;
  };
  auto args = std::make_shared<CancelArgs>();
  CLI::App* cmd = app.add_subcommand("cancel", "Cancel a farm job");
  cmd->add_option("job", args->job, "Job id")->required();
  AddServerOptions(cmd, args->server);
  cmd->callback([args] { std::cout << DescribeJob(ConnectToCoordinator(args->server)->Cancel(args->job)) << "\n"; });
}

}  // namespace lightfarm::cli
