// The rule scene-file paths follow on the farm: one function, used by the coordinator (accepting a
// manifest) and by every worker (materializing it), so they cannot disagree.
#include <gtest/gtest.h>

#include <string>

#include "common/farm/farm_protocol.h"

namespace lightfarm {
namespace test_farm_protocol {

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
