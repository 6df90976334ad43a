// Storage is bounded and checked: `lightfarm delete`, the retention policy and the collection of
// blobs no job references (never one a job or an upcoming submit needs), and the background
// scrub that finds a corrupted blob before anyone asks for it and has it made again.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "common/farm/content_hash.h"
#include "tests/integration/farm_harness.h"

namespace lightfarm {
namespace test_farm_upkeep {

using namespace lightfarm::testing;
namespace fs = std::filesystem;

std::vector<std::string> JobArgs(int seed) {
  return {"--method", "brute", "--resolution", "16x16", "--lights", "300", "--seed", std::to_string(seed)};
}

size_t StoredBlobs(const std::string& state) {
  size_t n = 0;
  for (const auto& e : fs::directory_iterator(state + "/blobs"))
    n += e.is_regular_file() && IsSha256Hex(e.path().filename().string());
  return n;
}

// Submits with --wait, returns the job id (from the stats beside --out).
std::string SubmitAndWait(const TempDir& dir, const std::string& address, int seed, const std::string& out) {
  std::vector<std::string> args = {"submit", ExampleCornellBox(), "--server", address, "--wait", "--quiet", "--out", out};
  for (const std::string& a : JobArgs(seed)) args.push_back(a);
  CliResult r = RunCli(dir, args);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  if (r.exit_code != 0) return "";
  const std::string stats = out.substr(0, out.size() - 4) + ".json";
  return nlohmann::json::parse(Slurp(stats))["farm"]["job_id"];
}

template <typename Pred>
bool WaitUntil(Pred pred, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(int64_t(seconds * 1000));
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return pred();
}

// Two jobs share the scene's files. Deleting one forgets it (NOT_FOUND) and collects only what
// it alone used; the other still fetches; deleting both empties the store.
TEST(FarmUpkeep, DeleteForgetsAJobAndTheCollectionKeepsWhatOthersUse) {
  TempDir dir;
  const std::string state = dir.Path("state");
  CoordinatorProcess coordinator(dir, state, {"--gc-interval-s", "0.2", "--gc-grace-s", "0"});
  auto worker = StartWorker(dir, coordinator.address());
  const std::string a = SubmitAndWait(dir, coordinator.address(), 1, dir.Path("a.exr"));
  const std::string b = SubmitAndWait(dir, coordinator.address(), 2, dir.Path("b.exr"));
  ASSERT_FALSE(a.empty());
  ASSERT_FALSE(b.empty());
  const size_t both = StoredBlobs(state);

  CliResult del = RunCli(dir, {"delete", a, "--server", coordinator.address()});
  ASSERT_EQ(del.exit_code, 0) << del.err;
  EXPECT_NE(del.out.find("deleted"), std::string::npos);
  CliResult status = RunCli(dir, {"status", a, "--server", coordinator.address()});
  EXPECT_NE(status.exit_code, 0);
  EXPECT_NE(status.err.find("NOT_FOUND"), std::string::npos) << status.err;
  EXPECT_TRUE(WaitUntil([&] { return StoredBlobs(state) < both; }, 10)) << StoredBlobs(state) << " of " << both;
  CliResult fetched = RunCli(dir, {"fetch", b, "--server", coordinator.address(), "--out", dir.Path("b2.exr")});
  ASSERT_EQ(fetched.exit_code, 0) << fetched.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("b2.exr")), ReadImage(dir.Path("b.exr"))));
  {
    StateDb db(state + "/state.sqlite");
    EXPECT_EQ(db.Query("SELECT COUNT(*) FROM tasks WHERE job_id = " + a)[0][0], 0);
    EXPECT_EQ(db.Query("SELECT COUNT(*) FROM attempts WHERE job_id = " + a)[0][0], 0);
  }
  ASSERT_EQ(RunCli(dir, {"delete", b, "--server", coordinator.address()}).exit_code, 0);
  EXPECT_TRUE(WaitUntil([&] { return StoredBlobs(state) == 0; }, 10)) << StoredBlobs(state);
  // Ids are never reused.
  const std::string c = SubmitAndWait(dir, coordinator.address(), 1, dir.Path("c.exr"));
  EXPECT_GT(std::stoll(c), std::stoll(b));
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("c.exr")), ReadImage(dir.Path("a.exr"))));
}

// The collection runs every 0.1 s while jobs are submitted, finished and deleted one after
// another on the same scene (its blobs unreferenced between jobs): every submit finds its files,
// every job renders the same bits. The grace period covers the gap between a client's upload
// check and its submit.
TEST(FarmUpkeep, CollectionUnderConcurrentSubmitsNeverRemovesANeededBlob) {
  TempDir dir;
  const std::string state = dir.Path("state");
  CoordinatorProcess coordinator(dir, state, {"--gc-interval-s", "0.1", "--gc-grace-s", "3"});
  auto worker = StartWorker(dir, coordinator.address());
  const std::string first = SubmitAndWait(dir, coordinator.address(), 4, dir.Path("first.exr"));
  ASSERT_FALSE(first.empty());
  for (int i = 0; i < 6; ++i) {
    const std::string out = dir.Path("run" + std::to_string(i) + ".exr");
    const std::string job = SubmitAndWait(dir, coordinator.address(), 4, out);
    ASSERT_FALSE(job.empty()) << "run " << i;
    EXPECT_TRUE(SameBits(ReadImage(out), ReadImage(dir.Path("first.exr")))) << "run " << i;
    ASSERT_EQ(RunCli(dir, {"delete", job, "--server", coordinator.address()}).exit_code, 0);
  }
  // What no kept job names (the light set and receivers, needed only while a job runs) goes once
  // its grace period is over.
  const size_t after_runs = StoredBlobs(state);
  EXPECT_TRUE(WaitUntil([&] { return StoredBlobs(state) < after_runs; }, 10)) << after_runs;
  CliResult fetched = RunCli(dir, {"fetch", first, "--server", coordinator.address(), "--out", dir.Path("again.exr")});
  ASSERT_EQ(fetched.exit_code, 0) << fetched.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("again.exr")), ReadImage(dir.Path("first.exr"))));
}

// --retain-finished-s: a finished job is deleted that long after it ended.
TEST(FarmUpkeep, TheRetentionPolicyDeletesFinishedJobs) {
  TempDir dir;
  const std::string state = dir.Path("state");
  CoordinatorProcess coordinator(dir, state,
                                 {"--retain-finished-s", "1", "--gc-interval-s", "0.2", "--gc-grace-s", "0"});
  auto worker = StartWorker(dir, coordinator.address());
  const std::string job = SubmitAndWait(dir, coordinator.address(), 3, dir.Path("out.exr"));
  ASSERT_FALSE(job.empty());
  RenderClient client = coordinator.Client();
  EXPECT_TRUE(WaitUntil([&] { return client.ListJobs().empty(); }, 15));
  EXPECT_TRUE(WaitUntil([&] { return StoredBlobs(state) == 0; }, 10)) << StoredBlobs(state);
}

// The scrub re-hashes the store in the background: a finished job's result image flipped on disk
// while the coordinator runs is found, quarantined and made again from the stored tasks, before
// anyone fetches it.
TEST(FarmUpkeep, TheScrubFindsACorruptedResultAndItIsMadeAgain) {
  TempDir dir;
  const std::string state = dir.Path("state");
  CoordinatorProcess coordinator(dir, state, {"--scrub-mb-per-s", "64"});
  auto worker = StartWorker(dir, coordinator.address());
  const std::string job = SubmitAndWait(dir, coordinator.address(), 6, dir.Path("first.exr"));
  ASSERT_FALSE(job.empty());
  std::string sha;
  {
    StateDb db(state + "/state.sqlite");
    sha = db.QueryText("SELECT result_sha FROM jobs WHERE id = " + job);
  }
  {
    std::fstream f(state + "/blobs/" + sha, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(100);
    f.put('\x7f');
  }
  EXPECT_TRUE(WaitUntil([&] { return !fs::is_empty(state + "/blobs/quarantine"); }, 20));
  // Made again: the job's recorded result is an intact blob again.
  RenderClient client = coordinator.Client();
  EXPECT_TRUE(WaitUntil([&] {
    StateDb db(state + "/state.sqlite");
    const std::string now = db.QueryText("SELECT result_sha FROM jobs WHERE id = " + job);
    if (client.GetJob(job).state() != v1::JOB_STATE_DONE || now.empty()) return false;
    const std::string path = state + "/blobs/" + now;
    return fs::exists(path) && Sha256OfFile(path) == now;  // intact (a new file, or the same bytes again)
  }, 30)) << coordinator.process().err() << client.GetJob(job).DebugString();
  CliResult fetched = RunCli(dir, {"fetch", job, "--server", coordinator.address(), "--out", dir.Path("again.exr")});
  ASSERT_EQ(fetched.exit_code, 0) << fetched.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("again.exr")), ReadImage(dir.Path("first.exr"))));
}

}  // namespace test_farm_upkeep
}  // namespace lightfarm
