// `lightfarm-coordinator` and `lightfarm-worker` over a table of bad invocations: each exits with
// a non-zero code (2 for a bad option value, 1 for a resource that cannot be used), prints exactly
// one line on stderr naming the problem, and never crashes or hangs. (`lightfarm`'s own options:
// tests/stability/test_bad_input_cli.cpp.)
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "tests/integration/farm_harness.h"

namespace lightfarm {
namespace test_farm_cli_options {

using namespace lightfarm::testing;

struct BadCall {
  std::vector<std::string> args;
  int exit_code;       // expected
  std::string where;   // must appear in the message
};

void ExpectOneLineFailure(const TempDir& dir, const std::string& binary, const BadCall& c, int counter) {
  std::vector<std::string> argv = {binary};
  argv.insert(argv.end(), c.args.begin(), c.args.end());
  std::string label = binary.substr(binary.rfind('/') + 1);
  for (const std::string& a : c.args) label += " " + a;
  Process p(argv, dir.Path("bad-" + std::to_string(counter)));
  const int code = p.Wait(30);
  EXPECT_EQ(code, c.exit_code) << label << "\n" << p.err();
  const std::string err = p.err();
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << label << "\n" << err;
  EXPECT_NE(err.find(c.where), std::string::npos) << label << "\n" << err;
  EXPECT_EQ(p.out(), "") << label;
}

TEST(FarmCliOptions, EveryBadCoordinatorOptionIsOneLine) {
  TempDir dir;
  const std::string state = dir.Path("state");
  const std::vector<std::string> base = {"--listen", "127.0.0.1:0", "--state-dir", state};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = base;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  const std::vector<BadCall> bad = {
      {{}, 2, "--listen is required"},
      {{"--listen", "127.0.0.1:0"}, 2, "--state-dir is required"},
      {{"--listen", "127.0.0.1:99999", "--state-dir", state}, 2, "port 99999"},
      {{"--listen", "127.0.0.1:-1", "--state-dir", state}, 2, "--listen"},
      {{"--listen", "127.0.0.1", "--state-dir", state}, 2, "HOST:PORT"},
      {{"--listen", ":5000", "--state-dir", state}, 2, "no host"},
      {{"--listen", "127.0.0.1:http", "--state-dir", state}, 2, "--listen"},
      {{"--listen", "8.8.8.8:5000", "--state-dir", state}, 1, "cannot listen on 8.8.8.8:5000"},
      {{"--listen", "127.0.0.1:0", "--state-dir", "/proc/no/such"}, 1, "/proc/no/such"},
      {with({"--bogus"}), 2, "--bogus"},
      {with({"--token-file", "/no/such/token"}), 1, "/no/such/token"},
      {with({"--tls-cert", "/no/such.pem", "--tls-key", "/no/such.key"}), 1, "/no/such"},
      {with({"--tls-cert", "/no/such.pem"}), 1, "--tls-key"},
      {with({"--metrics-listen", "127.0.0.1:70000"}), 2, "--metrics-listen"},
      {with({"--metrics-listen", "nohost"}), 2, "--metrics-listen"},
      {with({"--lease-timeout", "-1"}), 2, "--lease-timeout"},
      {with({"--lease-timeout", "abc"}), 2, "--lease-timeout"},
      {with({"--max-attempts", "0"}), 2, "--max-attempts"},
      {with({"--max-blob-mb", "0"}), 2, "--max-blob-mb"},
      {with({"--max-blob-mb", "-5"}), 2, "--max-blob-mb"},
      {with({"--max-resolution", "0"}), 2, "--max-resolution"},
      {with({"--max-lights", "0"}), 2, "--max-lights"},
      {with({"--max-lights", "-1"}), 2, "--max-lights"},
      {with({"--max-spp", "-1"}), 2, "--max-spp"},
      {with({"--max-active-jobs", "0"}), 2, "--max-active-jobs"},
      {with({"--max-queued-jobs", "x"}), 2, "--max-queued-jobs"},
      {with({"--planner-threads", "-2"}), 2, "--planner-threads"},
      {with({"--rpc-threads", "100000"}), 2, "--rpc-threads"},
      {with({"--drain-seconds", "-1"}), 2, "--drain-seconds"},
      {with({"--log-level", "loud"}), 2, "--log-level"},
      {with({"--lease-timeout", "nan"}), 2, "--lease-timeout"},
      {with({"--drain-seconds", "nan"}), 2, "--drain-seconds"},
  };
  int counter = 0;
  for (const BadCall& c : bad) ExpectOneLineFailure(dir, LIGHTFARM_COORDINATOR_PATH, c, counter++);
}

TEST(FarmCliOptions, EveryBadWorkerOptionIsOneLine) {
  TempDir dir;
  const std::vector<std::string> base = {"--coordinator", "127.0.0.1:1"};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = base;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  const std::vector<BadCall> bad = {
      {{}, 2, "--coordinator is required"},
      {{"--coordinator", "nohost"}, 2, "HOST:PORT"},
      {{"--coordinator", "127.0.0.1:0"}, 2, "port 0"},
      {{"--coordinator", "127.0.0.1:65536"}, 2, "port 65536"},
      {{"--coordinator", ""}, 2, "--coordinator"},
      {with({"--bogus"}), 2, "--bogus"},
      {with({"--threads", "-1"}), 2, "--threads"},
      {with({"--threads", "abc"}), 2, "--threads"},
      {with({"--cache-gb", "0"}), 2, "--cache-gb"},
      {with({"--poll-interval", "0"}), 2, "--poll-interval"},
      {with({"--poll-interval", "nan"}), 2, "--poll-interval"},
      {with({"--log-level", "x"}), 2, "--log-level"},
      {with({"--token-file", "/no/such/token"}), 1, "/no/such/token"},
      {with({"--tls-ca", "/no/such.pem"}), 1, "/no/such.pem"},
      {with({"--cache-dir", "/proc/no/such"}), 1, "/proc/no/such"},
  };
  int counter = 0;
  for (const BadCall& c : bad) ExpectOneLineFailure(dir, LIGHTFARM_WORKER_PATH, c, counter++);
}

// The farm commands of `lightfarm` check --server the same way, before connecting.
TEST(FarmCliOptions, BadServerAddressesAreRejectedBeforeConnecting) {
  TempDir dir;
  for (const std::string address : {"nohost", "127.0.0.1:0", "127.0.0.1:70000", ":1", "127.0.0.1:x"}) {
    const CliResult r = RunCli(dir, {"status", "--server", address, "--timeout", "60"}, 30);
    EXPECT_EQ(r.exit_code, 2) << address << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << address << "\n" << r.err;
    EXPECT_NE(r.err.find("--server"), std::string::npos) << r.err;
  }
  // Regression: NaN passed CLI::Range (every comparison with NaN is false).
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"status", "--server", "127.0.0.1:1", "--timeout", "nan"},
        std::vector<std::string>{"watch", "1", "--server", "127.0.0.1:1", "--preview-interval", "nan"}}) {
    const CliResult r = RunCli(dir, args, 30);
    EXPECT_EQ(r.exit_code, 2) << args[3] << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find("nan"), std::string::npos) << r.err;
  }
}

}  // namespace test_farm_cli_options
}  // namespace lightfarm
