// Each `lightfarm` subcommand lives in its own file and registers itself on the app.
// Commands throw (OptionError, SceneError, std::runtime_error); main() alone turns errors into
// a one-line message on stderr and a non-zero exit code.
#pragma once

#include <CLI/CLI.hpp>

namespace lightfarm::cli {

void AddRenderCommand(CLI::App& app);
void AddCompareCommand(CLI::App& app);
void AddBenchCommand(CLI::App& app);
void AddMethodsCommand(CLI::App& app);
// The farm's client commands (one file each).
void AddSubmitCommand(CLI::App& app);
void AddStatusCommand(CLI::App& app);
void AddWatchCommand(CLI::App& app);
void AddCancelCommand(CLI::App& app);
void AddDeleteCommand(CLI::App& app);
void AddPriorityCommand(CLI::App& app);
void AddWorkersCommand(CLI::App& app);
void AddFetchCommand(CLI::App& app);

}  // namespace lightfarm::cli
