// Storage faults are errors, not crashes: a full disk under --state-dir (a real tmpfs, filled to
// the last byte) refuses new work with RESOURCE_EXHAUSTED and pauses the accepted job, which
// completes with the same bits when space returns; a missing, empty or damaged database beside a
// store of blobs is refused with a message saying what to do.
#include <gtest/gtest.h>
#include <sys/mount.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "tests/integration/farm_harness.h"

namespace lightfarm {
namespace test_farm_storage {

using namespace lightfarm::testing;
namespace fs = std::filesystem;

// A tmpfs of `megabytes` mounted at `path` for the test's life (needs CAP_SYS_ADMIN: CI runs as
// root, as the README's set-up does).
class Tmpfs {
 public:
  Tmpfs(const std::string& path, int megabytes) : path_(path) {
    fs::create_directories(path);
    const std::string options = "size=" + std::to_string(megabytes) + "m";
    mounted_ = ::mount("tmpfs", path.c_str(), "tmpfs", 0, options.c_str()) == 0;
    if (!mounted_) error_ = std::strerror(errno);
  }
  ~Tmpfs() {
    if (mounted_) ::umount2(path_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }
  const std::string& error() const { return error_; }

 private:
  std::string path_, error_;
  bool mounted_ = false;
};

// Writes `path` until the file system refuses (or `leave_bytes` remain free); returns the bytes written.
uint64_t Fill(const std::string& path, uint64_t leave_bytes) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return 0;
  std::vector<char> block(64 << 10, 'x');
  uint64_t written = 0;
  for (;;) {
    const fs::space_info space = fs::space(fs::path(path).parent_path());
    if (space.available <= leave_bytes) break;
    const size_t n = size_t(std::min<uint64_t>(block.size(), space.available - leave_bytes));
    const size_t w = std::fwrite(block.data(), 1, n, f);
    written += w;
    if (w < n || std::fflush(f) != 0) break;
  }
  std::fclose(f);
  return written;
}

const std::vector<std::string> kJob = {"--method", "brute", "--resolution", "16x16", "--lights", "500", "--seed", "5"};

std::string SubmitNoWait(const TempDir& dir, const std::string& address, CliResult* result) {
  std::vector<std::string> args = {"submit", ExampleCornellBox(), "--server", address};
  args.insert(args.end(), kJob.begin(), kJob.end());
  *result = RunCli(dir, args);
  std::string id = result->out;
  while (!id.empty() && (id.back() == '\n' || id.back() == ' ')) id.pop_back();
  return id;
}

// The embedded render of kJob: the bits every farm run of it must give.
Image EmbeddedImage(const TempDir& dir) {
  std::vector<std::string> args = {"render", ExampleCornellBox(), "--out", dir.Path("embedded.exr"), "--quiet"};
  args.insert(args.end(), kJob.begin(), kJob.end());
  CliResult r = RunCli(dir, args);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return ReadImage(dir.Path("embedded.exr"));
}

// The disk fills to its last byte while a job runs (no reserve: every write that fails is a real
// ENOSPC from SQLite or the blob store).
TEST(FarmStorage, AFullDiskRefusesNewWorkAndTheAcceptedJobFinishesWhenSpaceReturns) {
  TempDir dir;
  const std::string mount = dir.Path("disk");
  Tmpfs tmpfs(mount, 24);
  ASSERT_TRUE(tmpfs.mounted()) << "mounting a tmpfs at " << mount << " failed (" << tmpfs.error()
                               << "): this test needs root, as CI has";
  const std::string state = mount + "/state";
  CoordinatorProcess coordinator(dir, state, {"--min-free-mb", "0", "--lease-timeout", "2"});
  RenderClient client = coordinator.Client();

  CliResult submitted;
  const std::string job = SubmitNoWait(dir, coordinator.address(), &submitted);
  ASSERT_EQ(submitted.exit_code, 0) << submitted.err;
  v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus& s) { return s.state() == v1::JOB_STATE_RUNNING; }, 60);
  ASSERT_EQ(st.state(), v1::JOB_STATE_RUNNING) << st.error();

  const uint64_t filled = Fill(mount + "/filler", 0);
  ASSERT_GT(filled, 0u);
  auto worker = StartWorker(dir, coordinator.address());
  // The worker's result cannot be stored: the coordinator says why and stays up.
  st = WaitForJob(client, job, [](const v1::JobStatus& s) { return s.waiting().find("disk is full") != std::string::npos; }, 60);
  EXPECT_NE(st.waiting().find("disk is full"), std::string::npos) << st.DebugString();
  EXPECT_EQ(st.state(), v1::JOB_STATE_RUNNING);
  std::this_thread::sleep_for(std::chrono::seconds(3));  // beyond the lease timeout: nothing fails
  ASSERT_TRUE(coordinator.process().running()) << coordinator.process().err();
  st = client.GetJob(job);
  EXPECT_EQ(st.state(), v1::JOB_STATE_RUNNING) << st.error();

  CliResult refused;
  SubmitNoWait(dir, coordinator.address(), &refused);
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.err.find("RESOURCE_EXHAUSTED"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("disk is full"), std::string::npos) << refused.err;

  fs::remove(mount + "/filler");
  st = WaitForJob(client, job, [](const v1::JobStatus&) { return false; }, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
  EXPECT_TRUE(st.waiting().empty());
  CliResult fetched = RunCli(dir, {"fetch", job, "--server", coordinator.address(), "--out", dir.Path("farm.exr")});
  ASSERT_EQ(fetched.exit_code, 0) << fetched.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("farm.exr")), EmbeddedImage(dir)));
  // And new work is taken again.
  CliResult again;
  const std::string next = SubmitNoWait(dir, coordinator.address(), &again);
  ASSERT_EQ(again.exit_code, 0) << again.err;
  st = WaitForJob(client, next, [](const v1::JobStatus&) { return false; }, 120);
  EXPECT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
  EXPECT_TRUE(coordinator.process().running());
}

// With the reserve (--min-free-mb), new work is refused before any write fails.
TEST(FarmStorage, BelowTheReserveSubmitsAndUploadsAreRefusedAtOnce) {
  TempDir dir;
  const std::string mount = dir.Path("disk");
  Tmpfs tmpfs(mount, 16);
  ASSERT_TRUE(tmpfs.mounted()) << "mounting a tmpfs at " << mount << " failed (" << tmpfs.error()
                               << "): this test needs root, as CI has";
  CoordinatorProcess coordinator(dir, mount + "/state", {"--min-free-mb", "8"});
  Fill(mount + "/filler", 4 << 20);  // 4 MiB left: below the 8 MiB reserve
  CliResult refused;
  SubmitNoWait(dir, coordinator.address(), &refused);
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.err.find("RESOURCE_EXHAUSTED"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("--min-free-mb"), std::string::npos) << refused.err;
  EXPECT_TRUE(coordinator.process().running());
  fs::remove(mount + "/filler");
  CliResult accepted;
  const std::string job = SubmitNoWait(dir, coordinator.address(), &accepted);
  EXPECT_EQ(accepted.exit_code, 0) << accepted.err;
  EXPECT_FALSE(job.empty());
}

// A state directory whose database is gone or empty but whose blobs are there is refused (the
// jobs would be forgotten and their ids reused), unless --fresh-state says so on purpose.
TEST(FarmStorage, AnEmptyOrMissingDatabaseBesideBlobsIsRefused) {
  TempDir dir;
  const std::string state = dir.Path("state");
  {
    CoordinatorProcess coordinator(dir, state, {});
    auto worker = StartWorker(dir, coordinator.address());
    std::vector<std::string> args = {"submit", ExampleCornellBox(), "--server", coordinator.address(), "--wait", "--quiet",
                                     "--out", dir.Path("one.exr")};
    args.insert(args.end(), kJob.begin(), kJob.end());
    CliResult r = RunCli(dir, args);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    coordinator.process().Kill(SIGTERM);
    coordinator.process().Wait(20);
  }
  for (const std::string damage : {"empty", "missing"}) {
    SCOPED_TRACE(damage);
    fs::remove(state + "/state.sqlite-wal");
    fs::remove(state + "/state.sqlite-shm");
    if (damage == "empty")
      std::ofstream(state + "/state.sqlite", std::ios::trunc);
    else
      fs::remove(state + "/state.sqlite");
    Process refused({LIGHTFARM_COORDINATOR_PATH, "--listen", "127.0.0.1:0", "--state-dir", state},
                    dir.Path("refused-" + damage));
    EXPECT_EQ(refused.Wait(30), 1);
    const std::string err = refused.err();
    EXPECT_NE(err.find(damage == "empty" ? "is empty" : "is missing"), std::string::npos) << err;
    EXPECT_NE(err.find("--fresh-state"), std::string::npos) << err;
    EXPECT_EQ(err.find("terminate"), std::string::npos) << err;
  }
  // On purpose: an empty farm starts, and says so.
  CoordinatorProcess fresh(dir, state, {"--fresh-state"});
  EXPECT_TRUE(fresh.process().running());
  EXPECT_TRUE(fresh.Client().ListJobs().empty());
  EXPECT_NE(fresh.process().err().find("starting an empty farm"), std::string::npos) << fresh.process().err();
}

// A database whose pages are damaged is refused by SQLite's integrity check at start.
TEST(FarmStorage, ADamagedDatabaseIsRefusedAtStart) {
  TempDir dir;
  const std::string state = dir.Path("state");
  {
    CoordinatorProcess coordinator(dir, state, {});
    coordinator.process().Kill(SIGTERM);
    coordinator.process().Wait(20);
  }
  const std::string db = state + "/state.sqlite";
  const uintmax_t size = fs::file_size(db);
  ASSERT_GT(size, 4096u);
  {
    // Past the header page: scribble over the schema's and tables' pages.
    std::fstream f(db, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(4096 + 16);
    const std::string junk(size_t(size - 4096 - 32), '\x5a');
    f.write(junk.data(), std::streamsize(junk.size()));
  }
  Process refused({LIGHTFARM_COORDINATOR_PATH, "--listen", "127.0.0.1:0", "--state-dir", state}, dir.Path("refused"));
  EXPECT_EQ(refused.Wait(30), 1);
  EXPECT_NE(refused.err().find("state.sqlite"), std::string::npos) << refused.err();
  EXPECT_EQ(refused.err().find("terminate"), std::string::npos) << refused.err();
}

}  // namespace test_farm_storage
}  // namespace lightfarm
