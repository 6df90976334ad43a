// Options and helpers shared by the farm subcommands (submit, status, watch, cancel, fetch):
// how to reach the coordinator, and writing a fetched result (EXR + PNG + stats JSON).
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "common/farm/render_client.h"

namespace lightfarm::cli {

struct ServerArgs {
  std::string server;
  std::string token_file;
  bool tls = false;
  std::string tls_ca;
  double timeout = 60;
};

void AddServerOptions(CLI::App* cmd, ServerArgs& args);
std::unique_ptr<RenderClient> ConnectToCoordinator(const ServerArgs& args);

// Writes FILE.exr (the bytes as fetched), FILE.png beside it, and the stats JSON to
// `stats_path` (default: FILE.json). Temporary files + rename: no partial output.
void WriteFetchedResult(const std::string& exr_path, const std::string& exr_bytes,
                        const std::string& stats_json, const std::string& stats_path);

// "job 3: running, stage 1/1 (gather), 5/10 tasks, eta 12.0s"
std::string DescribeJob(const v1::JobStatus& st);
// The progress bar's label: the stage, with "pass k/N" for a progressive job.
std::string ProgressPhase(const v1::JobStatus& st);

}  // namespace lightfarm::cli
