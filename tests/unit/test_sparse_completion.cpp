// `sparse-completion` (Huo et al. 2015) against brute force: exact when every entry of the reduced
// matrix is observed and every column is one light; a moderate error at a small fraction of the
// cost with the defaults; coarsening that never merges lights a wall separates; the same bits
// whatever the thread count.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <string>

#include "common/render/render_job.h"
#include "common/gather/gather.h"
#include "common/image/metrics.h"
#include "common/util/error.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_sparse_completion {

using testing::Elements;
using testing::ExpectImagesNear;

using testing::TempDir;

RenderOutput Render(const std::string& scene, const std::string& method,
                    std::vector<std::string> params, size_t lights, int res) {
  RenderSettings s;
  s.method = method;
  s.width = s.height = res;
  s.lights = lights;
  s.seed = 3;
  s.params = std::move(params);
  return RenderScene(scene, s);
}

double Stat(const RenderOutput& out, const char* key) {
  return out.stats["method_stats"][key].get<double>();
}


// Everything observed, no coarsening, a global cut down to the leaves: the completion is
// bypassed and every column is one light at scale 1, so the row sums are brute force's.
const std::vector<std::string> kExact = {"rate=1", "merge_error=0", "global_cut=1000000"};

TEST(SparseCompletion, FullSamplingWithoutCoarseningEqualsBruteForce) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput brute = Render(scene, "brute", {}, 500, 16);
  RenderOutput exact = Render(scene, "sparse-completion", kExact, 500, 16);
  ExpectImagesNear(brute.image, exact.image, 1e-5f);
  const double slices = exact.stats["slices"].get<double>();
  const double lights = exact.stats["lights"]["total"].get<double>();
  EXPECT_EQ(Stat(exact, "complete_slices"), slices);
  EXPECT_EQ(Stat(exact, "coarse_cut_nodes"), slices * lights);
  EXPECT_EQ(Stat(exact, "observed_entries"), Stat(exact, "reduced_entries"));
  EXPECT_EQ(Stat(exact, "observed_residual"), 0.0);
}

// Glossy receivers and VPLs, several emitters: still exact.
TEST(SparseCompletion, FullSamplingEqualsBruteForceWithGlossyMaterials) {
  const std::string scene = testing::SharedScene("veach-mis");
  RenderOutput brute = Render(scene, "brute", {}, 1500, 16);
  RenderOutput exact = Render(scene, "sparse-completion", kExact, 1500, 16);
  ExpectImagesNear(brute.image, exact.image, 1e-5f);
}

// Measured at these settings (seed 3): rel_l2 ≈ 0.05, rel_l1 ≈ 0.15 at rate 0.1 with under 1%
// of the elements; rate 0.3 roughly halves rel_l1. The error is per-row completion noise: 1 spp
// at 32² gives slices that span whole walls, far less coherent than the paper's 800-pixel
// patches of a 1024×768 image.
TEST(SparseCompletion, DefaultSettingsAreModeratelyAccurateAtASmallFractionOfTheCost) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput brute = Render(scene, "brute", {}, 5000, 32);
  RenderOutput sparse = Render(scene, "sparse-completion", {}, 5000, 32);
  ErrorMetrics m = CompareImages(brute.image, sparse.image);
  EXPECT_LT(m.rel_l2, 0.08);
  EXPECT_LT(m.rel_l1, 0.25);
  EXPECT_GT(m.rel_l2, 0.0);  // an approximation, not a copy of brute force
  EXPECT_LT(double(Elements(sparse)), 0.02 * double(Elements(brute)));
  EXPECT_LT(sparse.stats["rays"]["shadow"].get<double>(),
            0.02 * brute.stats["rays"]["shadow"].get<double>());
  // The coarsened cut is smaller than the global cut, and the slice's matrix mostly unobserved.
  EXPECT_LT(Stat(sparse, "coarse_cut_nodes"), Stat(sparse, "global_cut_nodes"));
  EXPECT_LT(Stat(sparse, "observed_entries"), 0.2 * Stat(sparse, "reduced_entries"));
  const double slices = sparse.stats["slices"].get<double>();
  EXPECT_GT(Stat(sparse, "observed_residual") / slices, 0.0);
  EXPECT_LT(Stat(sparse, "observed_residual") / slices, 0.5);
  // More samples, less error.
  RenderOutput denser = Render(scene, "sparse-completion", {"rate=0.3"}, 5000, 32);
  EXPECT_GT(Elements(denser), Elements(sparse));
  EXPECT_LT(CompareImages(brute.image, denser.image).rel_l1, 0.8 * m.rel_l1);
}

// Orthographic view of the floor z = 0 under two point lights at height 0.5, one on each side of
// a wall in the plane x = 0 (seen edge-on): every receiver sees exactly one of the lights.
std::string TwoLightScene(float x_left, float x_right, bool wall) {
  auto light = [](float x) {
    return "LightSource \"point\" \"rgb I\" [1 1 1] \"point3 from\" [" + std::to_string(x) +
           " 0.1 0.5]\n";
  };
  std::string s =
      "Film \"rgb\" \"integer xresolution\" [32] \"integer yresolution\" [32]\n"
      "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [1]\n"
      "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n"
      "WorldBegin\n" +
      light(x_left) + light(x_right) +
      "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
      "Shape \"trianglemesh\" \"point3 P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0]\n"
      "  \"integer indices\" [0 1 2 0 2 3]\n";
  if (wall)
    s += "Shape \"trianglemesh\" \"point3 P\" [0 -4 0  0 4 0  0 4 2  0 -4 2]\n"
         "  \"integer indices\" [0 1 2 0 2 3]\n";
  return s;
}

TEST(SparseCompletion, CoarseningNeverMergesLightsSeparatedByAWall) {
  TempDir dir;
  const std::string scene = dir.Write("wall.pbrt", TwoLightScene(-0.5f, 0.5f, true));
  // One slice holding both sides (its samples see each light on some rows and not on others),
  // then the default slices (each mostly on one side: one light bright, the other black).
  for (const char* slicing : {"rows_per_slice=100000", "rows_per_slice=800"}) {
    RenderOutput brute = Render(scene, "brute", {slicing}, 2, 32);
    RenderOutput sparse = Render(scene, "sparse-completion", {slicing, "rate=1"}, 2, 32);
    ASSERT_EQ(sparse.stats["lights"]["total"].get<int>(), 2);
    const double slices = sparse.stats["slices"].get<double>();
    EXPECT_EQ(Stat(sparse, "global_cut_nodes"), 2 * slices) << slicing;
    EXPECT_EQ(Stat(sparse, "coarse_cut_nodes"), 2 * slices) << slicing;
    // Kept apart and fully observed, the lights give brute force's image; a merged pair would
    // light each side from one position and leave the other half dark.
    ExpectImagesNear(brute.image, sparse.image, 1e-5f);
  }
}

// The control: two lights at the same place are one light to every receiver, and do merge (so
// the test above can fail). Merging identical lights is exact.
TEST(SparseCompletion, CoarseningMergesLightsThatNoReceiverCanTellApart) {
  TempDir dir;
  const std::string scene = dir.Write("same.pbrt", TwoLightScene(0.3f, 0.3f, false));
  RenderOutput brute = Render(scene, "brute", {}, 2, 32);
  RenderOutput sparse = Render(scene, "sparse-completion", {"rate=1"}, 2, 32);
  const double slices = sparse.stats["slices"].get<double>();
  EXPECT_EQ(Stat(sparse, "global_cut_nodes"), 2 * slices);
  EXPECT_EQ(Stat(sparse, "coarse_cut_nodes"), slices);
  ExpectImagesNear(brute.image, sparse.image, 1e-5f);
}

TEST(SparseCompletion, SameBitsWithOneAndTwoThreads) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput a, b;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    a = Render(scene, "sparse-completion", {"rows_per_slice=300"}, 2000, 24);
  }
  {
    tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
    b = Render(scene, "sparse-completion", {"rows_per_slice=300"}, 2000, 24);
  }
  ASSERT_GT(a.stats["slices"].get<int>(), 1);
  ASSERT_TRUE(a.image.SameSize(b.image));
  for (size_t i = 0; i < a.image.pixels.size(); ++i)
    ASSERT_EQ(a.image.pixels[i], b.image.pixels[i]) << "pixel " << i;
  EXPECT_EQ(Elements(a), Elements(b));
  EXPECT_EQ(a.stats["method_stats"], b.stats["method_stats"]);
}

TEST(SparseCompletion, InvalidParametersAreRejected) {
  for (const char* bad : {"rate=0", "rate=1.5", "rank=0", "global_cut=0", "merge_error=-1"}) {
    OptionMap params = OptionMap::Parse({bad});
    EXPECT_THROW(CreateGatherMethod("sparse-completion", params), OptionError) << bad;
  }
  OptionMap ok = OptionMap::Parse({"rate=0.05", "rank=8", "global_cut=300", "merge_error=0.01"});
  auto method = CreateGatherMethod("sparse-completion", ok);
  EXPECT_EQ(method->name(), "sparse-completion");
  EXPECT_TRUE(method->needs_light_tree());
  ok.RejectUnused();  // every parameter was read
}

}  // namespace test_sparse_completion
}  // namespace lightfarm
