// The rule scene-file paths follow on the farm: one function, used by the coordinator (accepting a
// manifest) and by every worker (materializing it), so they cannot disagree.
#include <gtest/gtest.h>

#include <string>

#include "common/farm/farm_protocol.h"
#include "common/farm/proto_convert.h"

namespace lightfarm {
namespace test_farm_protocol {

// The scheduler's plain job vocabulary and the wire's: the same values (the store keeps them as
// integers, so a database written before either reads the same), the same names.
TEST(FarmProtocol, PlainJobStatesAndManifestsAreTheWiresBothWays) {
  const JobState states[] = {JobState::kQueued, JobState::kPlanning, JobState::kRunning,
                             JobState::kDone, JobState::kFailed, JobState::kCancelled};
  const v1::JobState wire[] = {v1::JOB_STATE_QUEUED, v1::JOB_STATE_PLANNING, v1::JOB_STATE_RUNNING,
                               v1::JOB_STATE_DONE, v1::JOB_STATE_FAILED, v1::JOB_STATE_CANCELLED};
  for (size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(ToProto(states[i]), wire[i]);
    EXPECT_EQ(FromProto(wire[i]), states[i]);
    EXPECT_STREQ(JobStateName(states[i]), JobStateName(wire[i]));
    EXPECT_EQ(IsTerminal(states[i]), IsTerminal(wire[i]));
  }
  EXPECT_STREQ(JobStateName(v1::JOB_STATE_UNSPECIFIED), "unknown");
  EXPECT_FALSE(IsTerminal(v1::JOB_STATE_UNSPECIFIED));
  SceneManifest m;
  m.root = "scene.pbrt";
  m.files = {{"meshes/a.ply", std::string(64, 'a')}, {"scene.pbrt", std::string(64, 'b')}};
  const SceneManifest back = FromProto(ToProto(m));
  EXPECT_EQ(back.root, m.root);
  ASSERT_EQ(back.files.size(), 2u);
  EXPECT_EQ(back.files[0].path, "meshes/a.ply");
  EXPECT_EQ(back.RootSha256(), std::string(64, 'b'));
}

TEST(FarmProtocol, ScenePathsStayInsideTheSceneDirectory) {
  for (const char* ok : {"scene.pbrt", "meshes/bunny.ply", "tex/a..b.png", "a/b/c/..d", "..hidden", "x..", "a.b"})
    EXPECT_TRUE(IsSafeScenePath(ok)) << ok;
  for (const char* bad : {"", "/etc/passwd", "../x.pbrt", "a/../../x", "a/..", "./scene.pbrt", "a/./b",
                          "dir/", ".."})
    EXPECT_FALSE(IsSafeScenePath(bad)) << bad;
  EXPECT_FALSE(IsSafeScenePath(std::string("a\0b", 3)));
  EXPECT_FALSE(IsSafeScenePath(std::string(4097, 'a')));
  EXPECT_TRUE(IsSafeScenePath(std::string(4096, 'a')));
}

}  // namespace test_farm_protocol
}  // namespace lightfarm
