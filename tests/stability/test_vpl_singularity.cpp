// The lighting matrix's element (common/matrix/lighting_matrix.cpp) at the VPL singularity and at
// grazing angles: a light almost on the receiver, coincident points, lights in the receiver's
// tangent plane, with the geometry-term clamp off and on. Elements are finite and nonnegative
// always, and bounded by the clamp when it is on.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "common/matrix/lighting_matrix.h"
#include "tests/stability/stability_util.h"

namespace lightfarm {
namespace test_vpl_singularity {

using testing::BuildSceneFromText;

// A 2×2 diffuse floor at z = 0 (albedo 0.5, so f = 0.5/π), and an occluder far away.
const char* kFloor =
    "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\nWorldBegin\n"
    "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
    "Shape \"trianglemesh\" \"point3 P\" [-1 -1 0 1 -1 0 1 1 0 -1 1 0]"
    " \"integer indices\" [0 1 2 0 2 3]\n";

class VplSingularity : public ::testing::Test {
 protected:
  void SetUp() override {
    scene_ = BuildSceneFromText(kFloor);
    ShadingPoint sp;
    sp.p = Vec3(0.25f, -0.3f, 0.f);
    sp.ng = sp.ns = Vec3(0, 0, 1);
    sp.wo = Normalize(Vec3(0.1f, 0.2f, 1.f));
    sp.throughput = RGB(1.f);
    sp.material = uint32_t(scene_->shapes()[0].material);
    receivers_.points.push_back(sp);
    receivers_.width = receivers_.height = 1;
  }

  // The element of a light at `p` (offset from the receiver) of kind `kind`.
  RGB Element(const VirtualLight& light, float clamp) {
    lights_.lights = {light};
    MatrixOptions options;
    options.clamp = clamp;
    LightingMatrix matrix(*scene_, receivers_, lights_, options);
    MatrixCounters counters;
    return matrix.Element(0, 0, &counters);
  }

  VirtualLight AreaVpl(Vec3 offset, Vec3 n) const {
    VirtualLight l;
    l.kind = VirtualLightKind::kAreaVPL;
    l.p = receivers_.points[0].p + offset;
    l.n = l.ng = n;
    l.power = RGB(1.f);
    return l;
  }

  std::unique_ptr<Scene> scene_;
  ReceiverSet receivers_;
  LightSet lights_;
};

void ExpectFiniteNonnegative(RGB v, const std::string& what) {
  EXPECT_TRUE(v.IsFinite()) << what;
  EXPECT_GE(v.r, 0.f) << what;
  EXPECT_GE(v.g, 0.f) << what;
  EXPECT_GE(v.b, 0.f) << what;
}

TEST_F(VplSingularity, LightAlmostOnTheReceiverWithClampOffIsFinite) {
  for (float h : {1e-2f, 1e-6f, 1e-12f, 1e-19f, 1e-20f, 1e-22f, 1e-30f, 1e-40f, 1e-45f}) {
    const RGB v = Element(AreaVpl(Vec3(0, 0, h), Vec3(0, 0, -1)), 0.f);
    ExpectFiniteNonnegative(v, "height " + std::to_string(h));
  }
  // Where the value is representable it is the exact inverse-square law: ρ/π · cos · cos / d².
  const RGB v = Element(AreaVpl(Vec3(0, 0, 1e-2f), Vec3(0, 0, -1)), 0.f);
  EXPECT_NEAR(v.g, 0.5f / 3.14159265f / 1e-4f, 1e-3f * v.g);
}

TEST_F(VplSingularity, CoincidentPointsGiveZero) {
  for (float clamp : {0.f, 0.01f}) {
    const RGB v = Element(AreaVpl(Vec3(0, 0, 0), Vec3(0, 0, -1)), clamp);
    EXPECT_EQ(v.r, 0.f);
    EXPECT_EQ(v.g, 0.f);
    EXPECT_EQ(v.b, 0.f);
    VirtualLight point = AreaVpl(Vec3(0, 0, 0), Vec3(0, 0, -1));
    point.kind = VirtualLightKind::kPoint;
    ExpectFiniteNonnegative(Element(point, clamp), "coincident point light");
  }
}

TEST_F(VplSingularity, GrazingAnglesAreFinite) {
  for (float clamp : {0.f, 0.01f})
    for (float z : {0.f, 1e-7f, -1e-7f, 1e-30f, 1e-3f}) {
      // In (or within rounding of) the receiver's tangent plane, the light facing it...
      ExpectFiniteNonnegative(Element(AreaVpl(Vec3(1e-3f, 0, z), Vec3(-1, 0, 0)), clamp),
                              "side-on light z=" + std::to_string(z));
      // ...or seen edge-on itself.
      ExpectFiniteNonnegative(Element(AreaVpl(Vec3(0, 0, 0.5f), Normalize(Vec3(1, 0, z))), clamp),
                              "edge-on light z=" + std::to_string(z));
      // A surface VPL re-emitting at grazing angles, close to the receiver.
      VirtualLight s = AreaVpl(Vec3(1e-4f, 0, z), Normalize(Vec3(-1, 0, 1e-6f)));
      s.kind = VirtualLightKind::kSurfaceVPL;
      s.material = receivers_.points[0].material;
      s.wi = Normalize(Vec3(-1, 0, 1e-7f));
      ExpectFiniteNonnegative(Element(s, clamp), "surface VPL z=" + std::to_string(z));
    }
}

TEST_F(VplSingularity, ClampBoundsTheElement) {
  const float clamp = 0.01f;
  for (float h : {1e-1f, 1e-3f, 1e-8f, 1e-20f, 1e-38f}) {
    lights_.lights = {AreaVpl(Vec3(0, 0, h), Vec3(0, 0, -1))};
    MatrixOptions options;
    options.clamp = clamp;
    LightingMatrix matrix(*scene_, receivers_, lights_, options);
    MatrixCounters counters;
    const RGB v = matrix.Element(0, 0, &counters);
    ExpectFiniteNonnegative(v, "height " + std::to_string(h));
    const float d2 = matrix.clamp_distance() * matrix.clamp_distance();
    // ρ/π · 1 · 1 / d_min², with a float rounding margin.
    EXPECT_LE(v.g, 0.5f / 3.14159265f / d2 * 1.0001f) << h;
    EXPECT_TRUE(std::isfinite(counters.clamp_lost));
  }
}

TEST_F(VplSingularity, DegenerateLightValuesNeverReachTheSum) {
  std::vector<VirtualLight> lights;
  VirtualLight nan_power = AreaVpl(Vec3(0, 0, 1), Vec3(0, 0, -1));
  nan_power.power = RGB(std::numeric_limits<float>::quiet_NaN());
  VirtualLight inf_power = AreaVpl(Vec3(0, 0, 1), Vec3(0, 0, -1));
  inf_power.power = RGB(std::numeric_limits<float>::infinity());
  VirtualLight far_away = AreaVpl(Vec3(0, 0, 1e30f), Vec3(0, 0, -1));
  VirtualLight good = AreaVpl(Vec3(0, 0, 1), Vec3(0, 0, -1));
  lights_.lights = {nan_power, inf_power, far_away, good};
  LightingMatrix matrix(*scene_, receivers_, lights_, MatrixOptions{0.f});
  MatrixCounters counters;
  const RGBAccum sum = matrix.RowSum(0, &counters);
  EXPECT_TRUE(std::isfinite(sum.g));
  EXPECT_NEAR(sum.g, 0.5 / M_PI, 1e-6);  // only the good light counts
}

}  // namespace test_vpl_singularity
}  // namespace lightfarm
