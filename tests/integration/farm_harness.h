// Helpers for the multi-process farm tests: spawning the coordinator, workers and CLI as real
// processes on loopback, killing them, and reading the coordinator's SQLite state.
#pragma once

#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/generic/generic_stub.h>

#include <future>

#include "common/farm/render_client.h"
#include "common/image/image_io.h"
#include "tests/common/test_util.h"

namespace lightfarm::testing {

inline std::string Slurp(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// A child process with stdout/stderr in files; killed (SIGKILL) when the object dies.
class Process {
 public:
  Process(const std::vector<std::string>& argv, const std::string& log_prefix)
      : out_(log_prefix + ".out"), err_(log_prefix + ".err") {
    pid_ = fork();
    if (pid_ == 0) {
      FILE* o = freopen(out_.c_str(), "w", stdout);
      FILE* e = freopen(err_.c_str(), "w", stderr);
      (void)o;
      (void)e;
      std::vector<char*> args;
      for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      execv(args[0], args.data());
      _exit(127);
    }
  }
  ~Process() {
    if (running()) Kill(SIGKILL);
    Wait(10);
  }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const { return pid_; }
  std::string name;  // workers: the --name they registered with
  bool running() {
    if (exited_) return false;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      exited_ = true;
      exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      return false;
    }
    return true;
  }
  void Kill(int sig) {
    if (!exited_) kill(pid_, sig);
  }
  // Exit code, or -1 if still running after `seconds`.
  int Wait(double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(int64_t(seconds * 1000));
    while (running()) {
      if (std::chrono::steady_clock::now() > end) return -1;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return exit_code_;
  }
  std::string out() const { return Slurp(out_); }
  std::string err() const { return Slurp(err_); }

 private:
  pid_t pid_ = -1;
  std::string out_, err_;
  bool exited_ = false;
  int exit_code_ = -1;
};

struct CliResult {
  int exit_code = -1;
  std::string out, err;
};

inline CliResult RunCli(const TempDir& dir, const std::vector<std::string>& args, double timeout_s = 120) {
  static int counter = 0;
  std::vector<std::string> argv = {LIGHTFARM_CLI_PATH};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv, dir.Path("cli-" + std::to_string(counter++)));
  CliResult r;
  r.exit_code = p.Wait(timeout_s);
  r.out = p.out();
  r.err = p.err();
  return r;
}

// A coordinator process on 127.0.0.1 (a picked port, or a given one to restart on).
class CoordinatorProcess {
 public:
  CoordinatorProcess(const TempDir& dir, const std::string& state_dir, std::vector<std::string> extra,
                     int port = 0)
      : dir_(dir) {
    static int counter = 0;
    log_ = dir.Path("coordinator-" + std::to_string(counter++));
    std::vector<std::string> argv = {LIGHTFARM_COORDINATOR_PATH, "--listen",
                                     "127.0.0.1:" + std::to_string(port), "--state-dir", state_dir,
                                     "--log-level", "warn"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    process_ = std::make_unique<Process>(argv, log_);
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (std::chrono::steady_clock::now() < end) {
      std::string out = process_->out();
      size_t at = out.find("listening on port ");
      if (at != std::string::npos && out.find('\n', at) != std::string::npos) {
        port_ = std::stoi(out.substr(at + 18));
        return;
      }
      if (!process_->running()) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ADD_FAILURE() << "coordinator did not start: " << process_->err();
  }
  int port() const { return port_; }
  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  Process& process() { return *process_; }
  RenderClient Client(const std::string& token = "") const {
    ChannelOptions o;
    o.address = address();
    return RenderClient(MakeChannel(o), token, 30);
  }

 private:
  const TempDir& dir_;
  std::string log_;
  std::unique_ptr<Process> process_;
  int port_ = 0;
};

inline std::unique_ptr<Process> StartWorker(const TempDir& dir, const std::string& address,
                                            std::vector<std::string> extra = {}) {
  static int counter = 0;
  const std::string name = "worker-" + std::to_string(counter++);
  std::vector<std::string> argv = {LIGHTFARM_WORKER_PATH, "--coordinator", address, "--threads", "1",
                                   "--poll-interval", "0.02", "--cache-dir", dir.Path(name + "-cache"),
                                   "--name", name, "--log-level", "warn"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  auto p = std::make_unique<Process>(argv, dir.Path(name));
  p->name = name;
  return p;
}

// Polls the job until `pred` holds (or it ends), returns the last status.
template <typename Pred>
v1::JobStatus WaitForJob(RenderClient& client, const std::string& job, Pred pred, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(int64_t(timeout_s * 1000));
  v1::JobStatus st;
  while (std::chrono::steady_clock::now() < end) {
    try {
      st = client.GetJob(job);
      if (pred(st) || st.state() == v1::JOB_STATE_DONE || st.state() == v1::JOB_STATE_FAILED ||
          st.state() == v1::JOB_STATE_CANCELLED)
        return st;
    } catch (const RpcError&) {
      // the coordinator may be restarting
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  return st;
}

// grpc.health.v1.Health/Check for the whole server: true when SERVING. The request is an empty
// HealthCheckRequest; the response's field 1 (status) is SERVING = 1, encoded 08 01.
inline bool HealthServing(const std::string& address) {
  ChannelOptions o;
  o.address = address;
  grpc::GenericStub stub(MakeChannel(o));
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  grpc::ByteBuffer request, response;
  grpc::Slice empty("");
  request = grpc::ByteBuffer(&empty, 1);
  std::promise<grpc::Status> done;
  stub.UnaryCall(&ctx, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &response,
                 [&](grpc::Status st) { done.set_value(st); });
  grpc::Status st = done.get_future().get();
  if (!st.ok()) return false;
  std::vector<grpc::Slice> slices;
  (void)response.Dump(&slices);
  std::string bytes;
  for (const grpc::Slice& sl : slices) bytes.append(reinterpret_cast<const char*>(sl.begin()), sl.size());
  return bytes == std::string("\x08\x01", 2);
}

// Read-only queries on the coordinator's state database.
class StateDb {
 public:
  explicit StateDb(const std::string& path) {
    EXPECT_EQ(sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK) << path;
    sqlite3_busy_timeout(db_, 5000);
  }
  ~StateDb() { sqlite3_close(db_); }
  // First column of the first row as text ("" when there is none).
  std::string QueryText(const std::string& sql) {
    std::string out;
    sqlite3_stmt* st = nullptr;
    EXPECT_EQ(sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr), SQLITE_OK) << sqlite3_errmsg(db_);
    if (st && sqlite3_step(st) == SQLITE_ROW) {
      const void* p = sqlite3_column_blob(st, 0);
      out.assign(static_cast<const char*>(p ? p : ""), size_t(sqlite3_column_bytes(st, 0)));
    }
    sqlite3_finalize(st);
    return out;
  }
  std::vector<std::vector<int64_t>> Query(const std::string& sql) {
    std::vector<std::vector<int64_t>> rows;
    sqlite3_stmt* st = nullptr;
    EXPECT_EQ(sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr), SQLITE_OK) << sqlite3_errmsg(db_);
    while (st && sqlite3_step(st) == SQLITE_ROW) {
      std::vector<int64_t> row;
      for (int c = 0; c < sqlite3_column_count(st); ++c) row.push_back(sqlite3_column_int64(st, c));
      rows.push_back(row);
    }
    sqlite3_finalize(st);
    return rows;
  }

 private:
  sqlite3* db_ = nullptr;
};


}  // namespace lightfarm::testing
