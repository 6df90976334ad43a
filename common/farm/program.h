// What lightfarm's programs (lightfarm, lightfarm-coordinator, lightfarm-worker) set up alike:
// the floating-point mode, the log sink, the option validators and one-line parse errors.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <optional>
#include <string>

namespace lightfarm {

// Flushes denormals to zero. Call first in main, before any oneTBB task, so every worker thread
// inherits the mode: denormal arithmetic in BSDF tails is slow and meaningless here.
void SetFloatingPointMode();

// Log lines go to stderr (stdout carries data: the coordinator's port line, JSON), tagged with
// the program's role; gRPC's own lines go to our logger at debug level, so a failure is reported
// once, as the program's one-line error, not as gRPC's multi-line dump beside it.
void LogToStderr(const std::string& role);

// Parses the command line. nullopt: go on; otherwise the exit code to return: 0 after --help or
// --version, 2 after one line on stderr ("PROGRAM: what is wrong") for a bad option (CLI11_PARSE
// adds a second, "Run with --help ...").
std::optional<int> ParseCommandLine(CLI::App& app, int argc, char** argv, const std::string& program);

// Runs a program's body: whatever it throws is one line on stderr ("PROGRAM: what") and exit
// code 1; otherwise the body's code.
int RunProgram(const std::string& program, const std::function<int()>& body);

// SIGTERM and SIGINT are counted from now on (the handler only counts); StopSignals() is how
// many arrived, for a loop or a watcher thread to act on (no work in the handler).
void CatchStopSignals();
int StopSignals();

// CLI::Range for a floating-point option that also refuses NaN: CLI::Range tests
// `value < min || value > max`, which NaN passes (`--poll-interval nan` made the worker poll
// without ever sleeping, `--lease-timeout nan` an undefined lease length).
CLI::Validator FiniteRange(double min, double max);

// A HOST:PORT option (rpc.h's HostPortProblem): port 0 is allowed when `listen` (pick one).
CLI::Validator HostPort(bool listen);

// --log-level: trace|debug|info|warn|error|critical|off.
CLI::Validator LogLevel();

}  // namespace lightfarm
