// The per-process scene cache (scene_cache.h): a description parsed in one directory serves the
// same files materialized in another, rebased there, so that the scene builds from the new
// copy after the first is gone; other content parses anew; the least recently used goes first.
#include <gtest/gtest.h>

#include <filesystem>

#include "common/scene/scene.h"
#include "common/scene/scene_cache.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_scene_cache {

using namespace lightfarm::testing;
namespace fs = std::filesystem;

// A scene whose root is in sub/, with an Include and a PLY mesh the build reads, in `dir`.
void WriteScene(const TempDir& dir) {
  dir.Write("sub/scene.pbrt",
            "Film \"rgb\" \"integer xresolution\" [8] \"integer yresolution\" [8]\n"
            "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\nWorldBegin\n"
            "LightSource \"point\" \"rgb I\" [5 5 5] \"point3 from\" [0 0 3]\n"
            "Include \"../geo/quad.pbrt\"\n");
  dir.Write("geo/quad.pbrt", "Shape \"plymesh\" \"string filename\" \"../geo/mesh.ply\"\n");
  dir.Write("geo/mesh.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            "0 0 0\n2 0 0\n0 3 0\n3 0 1 2\n");
}

TEST(SceneCache, ASceneParsedInOneDirectoryBuildsFromItsCopyInAnother) {
  SceneCache cache;
  auto a = std::make_unique<TempDir>();
  TempDir b;
  WriteScene(*a);
  WriteScene(b);
  const std::string dir_a = a->Path(""), dir_b = b.Path("");
  const auto first = cache.Get("content", dir_a, "sub/scene.pbrt");
  EXPECT_EQ(cache.parses(), 1u);
  const Bounds3 bounds = Scene::Build(*first, {})->bounds();
  a.reset();  // the first copy is gone
  const auto second = cache.Get("content", dir_b, "sub/scene.pbrt");
  EXPECT_EQ(cache.parses(), 1u);
  EXPECT_EQ(cache.hits(), 1u);
  const fs::path b_root = fs::absolute(dir_b).lexically_normal();
  EXPECT_EQ(fs::path(second->base_dir), b_root / "sub");
  EXPECT_EQ(fs::path(second->root_file), b_root / "sub/scene.pbrt");
  ASSERT_EQ(second->files.size(), 3u);
  for (const std::string& f : second->files) {
    EXPECT_EQ(f.rfind(b_root.string(), 0), 0u) << f;
    EXPECT_TRUE(fs::exists(f)) << f << " is not in the second directory";
  }
  // The build reads the mesh from the second copy: the same scene.
  const Bounds3 again = Scene::Build(*second, {})->bounds();
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(again.lo[k], bounds.lo[k]);
    EXPECT_EQ(again.hi[k], bounds.hi[k]);
  }
  EXPECT_EQ(bounds.hi.y, 3.f);  // the mesh's own extent
  // Asked again in its own directory: the same description, not a copy.
  EXPECT_EQ(cache.Get("content", dir_b, "sub/scene.pbrt").get(), cache.Get("content", dir_b, "sub/scene.pbrt").get());
}

TEST(SceneCache, OtherContentParsesAndTheLeastRecentlyUsedIsDropped) {
  SceneCache cache(2);
  TempDir d;
  WriteScene(d);
  const std::string dir = d.Path("");
  cache.Get("one", dir, "sub/scene.pbrt");
  cache.Get("two", dir, "sub/scene.pbrt");
  EXPECT_EQ(cache.parses(), 2u);
  cache.Get("one", dir, "sub/scene.pbrt");  // "two" is now the least recently used
  cache.Get("three", dir, "sub/scene.pbrt");
  EXPECT_EQ(cache.parses(), 3u);
  cache.Get("one", dir, "sub/scene.pbrt");
  EXPECT_EQ(cache.parses(), 3u);
  cache.Get("two", dir, "sub/scene.pbrt");
  EXPECT_EQ(cache.parses(), 4u);
  // A scene that does not parse is an error naming file and line, and is not kept.
  d.Write("bad/scene.pbrt", "WorldBegin\nShape \"sphere\" \"float radius\" [oops]\n");
  EXPECT_THROW(cache.Get("bad", dir, "bad/scene.pbrt"), SceneError);
  EXPECT_THROW(cache.Get("bad", dir, "bad/scene.pbrt"), SceneError);
  EXPECT_EQ(cache.parses(), 4u);
}

}  // namespace test_scene_cache
}  // namespace lightfarm
