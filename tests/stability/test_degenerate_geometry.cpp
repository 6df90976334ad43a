// Degenerate geometry: zero-area triangles and duplicate vertices are dropped (they hold no
// surface) and the image is the one without them; values that would make a non-finite ray (NaN or
// Inf positions, normals or radii after the transform, overflowing areas) are a SceneError naming
// the shape and its file:line, before Embree ever sees them.
#include <gtest/gtest.h>

#include <string>

#include "common/render/render_job.h"
#include "common/scene/ply.h"
#include "common/util/error.h"
#include "tests/stability/stability_util.h"

namespace lightfarm {
namespace test_degenerate_geometry {

using testing::kQuad;
using testing::TempDir;

const char* kHeader =
    "Film \"rgb\" \"integer xresolution\" [16] \"integer yresolution\" [16]\n"
    "Integrator \"path\" \"integer maxdepth\" [2]\n"
    "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\nWorldBegin\n"
    "LightSource \"point\" \"rgb I\" [5 5 5] \"point3 from\" [0 0 3]\n";  // line 6

RenderOutput Render(const TempDir& dir, const std::string& world) {
  RenderSettings s;
  s.lights = 200;
  s.seed = 2;
  return RenderScene(dir.Write("scene.pbrt", kHeader + world), s);
}

// The scene fails with a SceneError whose message holds every piece of `expected`.
void ExpectSceneError(const TempDir& dir, const std::string& world,
                      const std::vector<std::string>& expected) {
  try {
    Render(dir, world);
    ADD_FAILURE() << "no error for:\n" << world;
  } catch (const SceneError& e) {
    for (const std::string& piece : expected)
      EXPECT_NE(std::string(e.what()).find(piece), std::string::npos)
          << "\"" << e.what() << "\" lacks \"" << piece << "\"";
  }
}

TEST(DegenerateGeometry, ZeroAreaTrianglesAndDuplicateVerticesAreDropped) {
  TempDir dir;
  const RenderOutput clean = Render(dir, kQuad);
  // The same quad with collinear, repeated-index and coincident-vertex triangles added.
  const RenderOutput messy = Render(
      dir,
      "Shape \"trianglemesh\" \"point3 P\" [-1 -1 0 1 -1 0 1 1 0 -1 1 0  0 0 0  0 0 0  0.5 0.5 0]"
      " \"integer indices\" [0 1 2 0 2 3  0 0 1  4 5 6  4 4 4  0 2 6  1 1 1]\n");
  testing::ExpectFiniteBounded(messy.image, 1e3f);
  EXPECT_EQ(messy.stats["film"]["nan_samples"], 0);
  testing::ExpectImagesNear(clean.image, messy.image, 1e-5f);
  // A mesh with nothing but degenerate triangles is skipped: the scene renders black.
  const RenderOutput empty = Render(
      dir, "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 1 1 2 2 2] \"integer indices\" [0 1 2]\n");
  testing::ExpectFiniteBounded(empty.image, 0.f);
}

TEST(DegenerateGeometry, NonFiniteValuesAfterTheTransformNameTheShape) {
  TempDir dir;
  // The parser refuses NaN/Inf literals; they still arise from finite numbers that overflow.
  ExpectSceneError(dir, "Scale 1e30 1e30 1e30\n" + kQuad,
                   {"scene.pbrt:8:", "Shape \"trianglemesh\"", "too large for float"});
  ExpectSceneError(dir, "Translate 3e38 0 0\nTranslate 3e38 0 0\n" + kQuad,
                   {"scene.pbrt:9:", "Shape \"trianglemesh\""});
  ExpectSceneError(dir, "Scale 1e20 1e20 1e20\nShape \"sphere\" \"float radius\" [1e20]\n",
                   {"scene.pbrt:8:", "Shape \"sphere\""});
  ExpectSceneError(dir, "Translate 3e38 0 0\nTranslate 3e38 0 0\nShape \"sphere\"\n",
                   {"scene.pbrt:9:", "Shape \"sphere\""});
  ExpectSceneError(dir, "Scale 1e20 1e20 1e20\nShape \"disk\" \"float radius\" [1e20]\n",
                   {"scene.pbrt:8:", "Shape \"disk\""});
}

// Regression: such a scene used to run out of memory (killed) instead of failing.
TEST(DegenerateGeometry, OverflowingAreaOfAnEmitterIsAnError) {
  TempDir dir;
  ExpectSceneError(dir,
                   "AreaLightSource \"diffuse\" \"rgb L\" [1e30 1e30 1e30] \"float scale\" [1e30]\n" +
                       kQuad,
                   {"scene.pbrt:7:", "Shape \"trianglemesh\"", "not finite"});
  // Finite vertices whose triangle area is not representable: an infinite emitted power.
  ExpectSceneError(dir,
                   "AreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n"
                   "Shape \"trianglemesh\" \"point3 P\" [-1e20 -1e20 0 1e20 -1e20 0 1e20 1e20 0]"
                   " \"integer indices\" [0 1 2]\n",
                   {"scene.pbrt:8:", "Shape \"trianglemesh\""});
}

// Regression: an environment whose power overflows float made NaN light counts and a huge
// allocation (std::bad_alloc, or the OOM killer) instead of an error.
TEST(DegenerateGeometry, OverflowingEnvironmentPowerIsAnError) {
  TempDir dir;
  ExpectSceneError(dir,
                   "LightSource \"infinite\" \"rgb L\" [1e38 1e38 1e38] \"float scale\" [1e30]\n" + kQuad,
                   {"scene.pbrt:7:", "LightSource \"infinite\"", "not finite"});
  // Finite radiance, but a scene so large that the environment's power (radiance × 4π × the
  // scene's disk) overflows.
  try {
    Render(dir, "LightSource \"infinite\" \"rgb L\" [1e30 1e30 1e30]\nScale 1e8 1e8 1e8\n" + kQuad);
    ADD_FAILURE() << "no error for an overflowing environment power";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("overflows"), std::string::npos) << e.what();
  }
}

TEST(DegenerateGeometry, ZeroLengthNormalsNeverMakeANanSample) {
  TempDir dir;
  // Zero normals (and normals that collapse under the transform) carry no direction.
  for (const std::string& world :
       {std::string("Shape \"trianglemesh\" \"point3 P\" [-1 -1 0 1 -1 0 1 1 0 -1 1 0]"
                    " \"normal N\" [0 0 0 0 0 0 0 0 0 0 0 0] \"integer indices\" [0 1 2 0 2 3]\n"),
        std::string("Shape \"trianglemesh\" \"point3 P\" [-1 -1 0 1 -1 0 1 1 0 -1 1 0]"
                    " \"normal N\" [0 0 1e-30 0 0 1 0 0 1 0 0 1] \"integer indices\" [0 1 2 0 2 3]\n")}) {
    try {
      const RenderOutput out = Render(dir, world);
      testing::ExpectFiniteBounded(out.image, 1e3f);
      EXPECT_EQ(out.stats["film"]["nan_samples"], 0);
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("scene.pbrt:7:"), std::string::npos) << e.what();
    }
  }
}

TEST(DegenerateGeometry, NonFinitePlyDataNamesTheFile) {
  TempDir dir;
  // A binary PLY can hold NaN and Inf directly.
  PlyMesh mesh;
  mesh.positions = {Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0)};
  mesh.indices = {0, 1, 2};
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    PlyMesh m = mesh;
    m.positions[1].y = bad;
    WritePly(dir.Path("bad.ply"), m, "binary_little_endian");
    try {
      Render(dir, "Shape \"plymesh\" \"string filename\" \"bad.ply\"\n");
      ADD_FAILURE() << "no error for a non-finite PLY vertex";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.ply"), std::string::npos) << e.what();
    }
  }
}

TEST(DegenerateGeometry, DegenerateCameraIsAnError) {
  TempDir dir;
  for (const std::string& camera : {std::string("LookAt 0 0 5  0 0 5  0 1 0\n"),
                                    std::string("LookAt 0 0 5  0 0 0  0 0 1\n"),
                                    std::string("Scale 0 1 1\n")}) {
    const std::string text =
        "Film \"rgb\" \"integer xresolution\" [8] \"integer yresolution\" [8]\n" + camera +
        "Camera \"perspective\"\nWorldBegin\n" + kQuad;
    try {
      RenderSettings s;
      s.lights = 10;
      RenderScene(dir.Write("cam.pbrt", text), s);
      ADD_FAILURE() << "no error for " << camera;
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("cam.pbrt:"), std::string::npos) << e.what();
    }
  }
}

}  // namespace test_degenerate_geometry
}  // namespace lightfarm
