// `lightfarm status [JOB] --server HOST:PORT [--json]`: one job's state, or every job's.
#include <google/protobuf/util/json_util.h>

#include <iostream>

#include "cli/commands.h"
#include "cli/farm_options.h"

namespace lightfarm::cli {

namespace {

struct StatusArgs {
  std::string job;
  ServerArgs server;
  bool json = false;
};

void Print(const v1::JobStatus& st, bool json) {
  if (!json) {
    std::cout << DescribeJob(st) << "\n";
    return;
  }
  std::string out;
  google::protobuf::util::JsonPrintOptions opt;
  opt.always_print_primitive_fields = true;
  opt.preserve_proto_field_names = true;
  (void)google::protobuf::util::MessageToJsonString(st, &out, opt);
  std::cout << out << "\n";
}

}  // namespace

void AddStatusCommand(CLI::App& app) {
  auto args = std::make_shared<StatusArgs>();
  CLI::App* cmd = app.add_subcommand("status", "Show a farm job's state (all jobs without JOB)");
  cmd->add_option("job", args->job, "Job id");
  AddServerOptions(cmd, args->server);
  cmd->add_flag("--json", args->json, "Print JSON");
  cmd->callback([args] {
    auto client = ConnectToCoordinator(args->server);
    if (!args->job.empty()) {
      Print(client->GetJob(args->job), args->json);
      return;
    }
    for (const v1::JobStatus& st : client->ListJobs()) Print(st, args->json);
  });
}

}  // namespace lightfarm::cli
