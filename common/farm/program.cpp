#include "common/farm/program.h"

#include <grpc/support/log.h>
#include <pmmintrin.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <xmmintrin.h>

#include <cmath>
#include <csignal>
#include <iostream>

#include "common/farm/rpc.h"

namespace lightfarm {

namespace {

void GrpcLogToDebug(gpr_log_func_args* args) { spdlog::debug("grpc: {}", args->message); }

volatile std::sig_atomic_t g_stop_signals = 0;
void CountStopSignal(int) { g_stop_signals = g_stop_signals + 1; }

}  // namespace

void SetFloatingPointMode() {
  _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
  _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

void LogToStderr(const std::string& role) {
  spdlog::set_default_logger(spdlog::stderr_color_mt("lightfarm"));
  spdlog::set_pattern("[%H:%M:%S.%e] [" + role + "] [%l] %v");
  gpr_set_log_function(GrpcLogToDebug);
}

std::optional<int> ParseCommandLine(CLI::App& app, int argc, char** argv, const std::string& program) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << program << ": " << e.what() << "\n";
    return 2;
  }
  return std::nullopt;
}

int RunProgram(const std::string& program, const std::function<int()>& body) {
  try {
    return body();
  } catch (const std::exception& e) {
    std::cerr << program << ": " << e.what() << "\n";
    return 1;
  }
}

void CatchStopSignals() {
  std::signal(SIGTERM, CountStopSignal);
  std::signal(SIGINT, CountStopSignal);
}

int StopSignals() { return int(g_stop_signals); }

CLI::Validator FiniteRange(double min, double max) {
  CLI::Validator range = CLI::Range(min, max);
  return CLI::Validator(
      [range](std::string& value) {
        double v = 0;
        if (CLI::detail::lexical_cast(value, v) && std::isnan(v)) return std::string("Value nan is not a number");
        std::string copy = value;
        return range(copy);
      },
      range.get_description());
}

CLI::Validator HostPort(bool listen) {
  return CLI::Validator([listen](std::string& v) { return HostPortProblem(v, listen); }, "HOST:PORT");
}

CLI::Validator LogLevel() {
  return CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"});
}

}  // namespace lightfarm
