// `lightfarm watch JOB --server HOST:PORT`: follows a job until it ends: a progress bar with ETA
// on a terminal, one line per change otherwise. Exit code 0 only when the job is done.
#include <unistd.h>

#include <iostream>

#include "cli/commands.h"
#include "cli/farm_options.h"
#include "cli/progress.h"
#include "common/farm/proto_convert.h"

namespace lightfarm::cli {

void AddWatchCommand(CLI::App& app) {
  struct WatchArgs {
    std::string job;
    ServerArgs server;
  };
  auto args = std::make_shared<WatchArgs>();
  CLI::App* cmd = app.add_subcommand("watch", "Follow a farm job until it ends (progress, ETA)");
  cmd->add_option("job", args->job, "Job id")->required();
  AddServerOptions(cmd, args->server);
  cmd->callback([args] {
    auto client = ConnectToCoordinator(args->server);
    ProgressBar bar;
    const bool tty = isatty(STDERR_FILENO) != 0;
    std::string last;
    v1::JobStatus st = client->Watch(args->job, [&](const v1::JobStatus& s) {
      if (tty) {
        if (s.state() == v1::JOB_STATE_RUNNING) bar.Update(s.stage_name(), s.tasks_done(), s.tasks_total());
        return;
      }
      std::string line = DescribeJob(s);
      if (line != last) std::cout << line << std::endl;
      last = line;
    });
    bar.Finish();
    if (st.state() != v1::JOB_STATE_DONE) throw std::runtime_error(DescribeJob(st));
    std::cout << DescribeJob(st) << std::endl;
  });
}

}  // namespace lightfarm::cli
