// `lightfarm fetch JOB --server HOST:PORT --out FILE.exr [--stats FILE.json]`: downloads a
// finished job's image (EXR, plus a PNG beside it) and stats JSON.
#include "cli/commands.h"
#include "cli/farm_options.h"

namespace lightfarm::cli {

void AddFetchCommand(CLI::App& app) {
  struct FetchArgs {
    std::string job;
    ServerArgs server;
    std::string out = "out/result.exr";
    std::string stats;
  };
  auto args = std::make_shared<FetchArgs>();
  CLI::App* cmd = app.add_subcommand("fetch", "Download a finished farm job's image and stats");
  cmd->add_option("job", args->job, "Job id")->required();
  AddServerOptions(cmd, args->server);
  cmd->add_option("--out", args->out, "Output EXR (PNG and stats JSON beside it)");
  cmd->add_option("--stats", args->stats, "Stats JSON path (default: beside --out)");
  cmd->callback([args] {
    std::string exr, stats;
    ConnectToCoordinator(args->server)->Fetch(args->job, &exr, &stats);
    WriteFetchedResult(args->out, exr, stats, args->stats);
  });
}

}  // namespace lightfarm::cli
