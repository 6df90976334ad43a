// `lightfarm watch JOB --server HOST:PORT`: follows a job until it ends: a progress bar with ETA
// on a terminal, one line per change otherwise; `--preview FILE.png` keeps FILE.png showing the
// tiles finished so far. Exit code 0 only when the job is done.
#include <unistd.h>

#include <filesystem>
#include <iostream>

#include "cli/commands.h"
#include "cli/farm_options.h"
#include "cli/progress.h"
#include "common/farm/program.h"
#include "common/farm/proto_convert.h"
#include "common/util/file.h"

namespace lightfarm::cli {

void AddWatchCommand(CLI::App& app) {
  struct WatchArgs {
    std::string job;
    ServerArgs server;
    std::string preview;
    double preview_interval = 2;
  };
  auto args = std::make_shared<WatchArgs>();
  CLI::App* cmd = app.add_subcommand("watch", "Follow a farm job until it ends (progress, ETA)");
  cmd->add_option("job", args->job, "Job id")->required();
  AddServerOptions(cmd, args->server);
  cmd->add_option("--preview", args->preview, "Keep this PNG updated with the finished tiles");
  cmd->add_option("--preview-interval", args->preview_interval, "Seconds between previews")
      ->check(FiniteRange(0.25, 3600.0));
  cmd->callback([args] {
    auto client = ConnectToCoordinator(args->server);
    ProgressBar bar;
    const bool tty = isatty(STDERR_FILENO) != 0;
    std::string last;
    v1::JobStatus st = client->Watch(args->job, [&](const v1::JobStatus& s) {
      if (!args->preview.empty() && !s.preview_png().empty()) {
        // Replaced atomically: an image viewer never reads half of it.
        WriteFileAtomically(args->preview, s.preview_png());
      }
      if (tty) {
        if (s.state() == v1::JOB_STATE_RUNNING) bar.Update(ProgressPhase(s), s.tasks_done(), s.tasks_total());
        return;
      }
      std::string line = DescribeJob(s);
      if (line != last) std::cout << line << std::endl;
      last = line;
    }, 7 * 24 * 3600.0, args->preview.empty() ? 0.0 : args->preview_interval);
    bar.Finish();
    if (st.state() != v1::JOB_STATE_DONE) throw std::runtime_error(DescribeJob(st));
    std::cout << DescribeJob(st) << std::endl;
  });
}

}  // namespace lightfarm::cli
