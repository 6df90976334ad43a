// `lightfarm cancel JOB --server HOST:PORT`: stops a job; its queued tasks are dropped.
// `lightfarm delete JOB --server HOST:PORT`: forgets a job and what it stored.
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

void AddDeleteCommand(CLI::App& app) {
  struct DeleteArgs {
    std::string job;
    ServerArgs server;
  };
  auto args = std::make_shared<DeleteArgs>();
  CLI::App* cmd = app.add_subcommand(
      "delete", "Delete a farm job (cancelled first if unfinished): its result, stats and stored work");
  cmd->add_option("job", args->job, "Job id")->required();
  AddServerOptions(cmd, args->server);
  cmd->callback([args] {
    ConnectToCoordinator(args->server)->Delete(args->job);
    std::cout << "job " << args->job << " deleted\n";
  });
}

}  // namespace lightfarm::cli
