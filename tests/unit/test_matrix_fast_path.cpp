// The lighting matrix's Lambertian fast path must give exactly the general path's bits: every
// row, row sum, column and entry list of small plans on the shared scenes (all-diffuse
// cornell-box, glossy veach-mis, the media of volumetric-caustic), and the same counters.
#include <gtest/gtest.h>

#include <cstring>

#include "common/render/render_job.h"
#include "common/util/rng.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_matrix_fast_path {

bool SameBits(RGB a, RGB b) { return std::memcmp(&a, &b, sizeof(RGB)) == 0; }

void ExpectSameCounters(const MatrixCounters& a, const MatrixCounters& b) {
  EXPECT_EQ(a.elements, b.elements);
  EXPECT_EQ(a.shadow_rays, b.shadow_rays);
  EXPECT_EQ(a.transmittance_evals, b.transmittance_evals);
  EXPECT_EQ(a.clamp_lost, b.clamp_lost);
  EXPECT_EQ(a.clamp_kept, b.clamp_kept);
}

// Returns how many non-zero elements the rows checked had (so a test can insist on coverage).
size_t CompareFastAndGeneral(const std::string& scene, size_t lights) {
  RenderSettings s;
  s.width = s.height = 16;
  s.lights = lights;
  s.seed = 3;
  Plan plan = BuildPlan(testing::SharedScene(scene), s, nullptr);
  MatrixOptions general_options = plan.matrix_options;
  general_options.diffuse_fast_path = false;
  MatrixOptions fast_options = plan.matrix_options;
  fast_options.diffuse_fast_path = true;
  LightingMatrix general(*plan.scene, *plan.receivers, *plan.lights, general_options);
  LightingMatrix fast(*plan.scene, *plan.receivers, *plan.lights, fast_options);
  const size_t rows = fast.rows(), cols = fast.cols();
  MatrixCounters cg, cf;
  size_t nonzero = 0;
  std::vector<RGB> rg(cols), rf(cols);
  std::vector<uint32_t> some_rows;
  for (size_t r = 0; r < rows; r += std::max<size_t>(1, rows / 24)) {
    some_rows.push_back(uint32_t(r));
    general.Row(uint32_t(r), rg, &cg);
    fast.Row(uint32_t(r), rf, &cf);
    for (size_t j = 0; j < cols; ++j) {
      EXPECT_TRUE(SameBits(rg[j], rf[j])) << scene << " row " << r << " light " << j;
      nonzero += rf[j].IsBlack() ? 0 : 1;
    }
    RGBAccum sg = general.RowSum(uint32_t(r), &cg), sf = fast.RowSum(uint32_t(r), &cf);
    EXPECT_EQ(sg.r, sf.r);
    EXPECT_EQ(sg.g, sf.g);
    EXPECT_EQ(sg.b, sf.b);
  }
  std::vector<RGB> cgv(some_rows.size()), cfv(some_rows.size());
  for (size_t j = 0; j < cols; j += std::max<size_t>(1, cols / 40)) {
    general.Column(uint32_t(j), some_rows, cgv, &cg);
    fast.Column(uint32_t(j), some_rows, cfv, &cf);
    for (size_t k = 0; k < some_rows.size(); ++k)
      EXPECT_TRUE(SameBits(cgv[k], cfv[k])) << scene << " column " << j << " row " << some_rows[k];
  }
  // Arbitrary entries, mixed rows and lights in one batch.
  Rng rng(HashSeed({7, 0xFA57}));
  std::vector<uint32_t> er(1000), ec(1000);
  for (size_t k = 0; k < er.size(); ++k) {
    er[k] = rng.UniformInt(uint32_t(rows));
    ec[k] = rng.UniformInt(uint32_t(cols));
  }
  std::vector<RGB> eg(er.size()), ef(er.size());
  general.EvaluateEntries(er, ec, eg, &cg);
  fast.EvaluateEntries(er, ec, ef, &cf);
  for (size_t k = 0; k < er.size(); ++k)
    EXPECT_TRUE(SameBits(eg[k], ef[k])) << scene << " entry " << er[k] << "," << ec[k];
  ExpectSameCounters(cg, cf);
  return nonzero;
}

TEST(MatrixFastPath, CornellBoxSameBitsAsGeneralPath) {
  EXPECT_GT(CompareFastAndGeneral("cornell-box", 3000), 10000u);
}

TEST(MatrixFastPath, VeachMisSameBitsAsGeneralPath) {
  EXPECT_GT(CompareFastAndGeneral("veach-mis", 2000), 1000u);
}

TEST(MatrixFastPath, VolumetricCausticSameBitsAsGeneralPath) {
  EXPECT_GT(CompareFastAndGeneral("volumetric-caustic", 2000), 100u);
}

}  // namespace test_matrix_fast_path
}  // namespace lightfarm
