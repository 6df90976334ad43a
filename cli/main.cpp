// `lightfarm`: the command-line entry point. The only place (with the gRPC service boundary)
// where errors become a one-line message and an exit code.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "cli/commands.h"
#include "common/farm/program.h"
#include "common/util/error.h"

int main(int argc, char** argv) {
  lightfarm::SetFloatingPointMode();
  spdlog::set_pattern("%^[%l]%$ %v");
  spdlog::set_level(spdlog::level::warn);

  CLI::App app{"lightfarm: many-light rendering of pbrt-v4 scenes"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(LIGHTFARM_VERSION));
  lightfarm::cli::AddRenderCommand(app);
  lightfarm::cli::AddCompareCommand(app);
  lightfarm::cli::AddBenchCommand(app);
  lightfarm::cli::AddMethodsCommand(app);
  lightfarm::cli::AddSubmitCommand(app);
  lightfarm::cli::AddStatusCommand(app);
  lightfarm::cli::AddWatchCommand(app);
  lightfarm::cli::AddCancelCommand(app);
  lightfarm::cli::AddDeleteCommand(app);
  lightfarm::cli::AddPriorityCommand(app);
  lightfarm::cli::AddWorkersCommand(app);
  lightfarm::cli::AddFetchCommand(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "lightfarm: " << e.what() << "\n";
    return 2;
  } catch (const lightfarm::SceneError& e) {
    std::cerr << "lightfarm: " << e.what() << "\n";
    return 1;
  } catch (const lightfarm::OptionError& e) {
    std::cerr << "lightfarm: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "lightfarm: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
