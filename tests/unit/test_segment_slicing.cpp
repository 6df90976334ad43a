// Eye-segment slicing (Huo 2016, Sec. 4; common/receivers/segment_slicing.h): the similarity
// terms of Eqs. 8–12, the METIS partition (every segment in one slice, deterministic), and the
// boundary refinement (splits keep each camera sample's segments contiguous and their length).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <map>
#include <memory>

#include "common/image/filter.h"
#include "common/receivers/segment_slicing.h"
#include "common/receivers/svm_boundary.h"
#include "common/util/rng.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_segment_slicing {

// A camera looking into a fog sphere of radius 20 with a diffuse ball behind its centre.
std::unique_ptr<Scene> FogScene(int res) {
  SceneDescription desc = ParseSceneString(
      "Film \"rgb\" \"integer xresolution\" [" + std::to_string(res) +
          "] \"integer yresolution\" [" + std::to_string(res) +
          "]\n"
          "Integrator \"volpath\" \"integer maxdepth\" [5]\n"
          "LookAt 0 0 50  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\nWorldBegin\n"
          "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.01 0.01 0.01]\n"
          "  \"rgb sigma_s\" [0.03 0.03 0.03] \"float g\" [0.4]\n"
          "AttributeBegin\nMediumInterface \"fog\" \"\"\nMaterial \"interface\"\n"
          "Shape \"sphere\" \"float radius\" [20]\nAttributeEnd\n"
          "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
          "AttributeBegin\nTranslate 0 0 -30\nShape \"sphere\" \"float radius\" [5]\nAttributeEnd\n",
      "fog.pbrt", "/tmp");
  return Scene::Build(desc, SceneBuildOptions{});
}

ReceiverSet FogReceivers(const Scene& scene) {
  std::unique_ptr<Filter> filter = Filter::Create(FilterType::kBox, {0.5f, 0.5f}, FilterShape{});
  FilterSampler sampler(*filter);
  ReceiverOptions opt;
  opt.seed = 7;
  opt.segments_per_ray = 16;
  return GenerateReceivers(scene, sampler, opt);
}

SegmentSlicingOptions SmallSlices() {
  SegmentSlicingOptions o;
  o.min_rows_per_slice = 150;
  o.max_rows_per_slice = 300;
  o.seed = 7;
  return o;
}

SegmentFeatures Feature(Vec3 x0, Vec3 x1, float g, float tau, float px, float py) {
  SegmentFeatures f;
  f.x0 = x0;
  f.x1 = x1;
  f.d = Normalize(x1 - x0);
  f.g = g;
  f.tau = tau;
  f.px = px;
  f.py = py;
  f.medium = 0;
  return f;
}

void ExpectEverySegmentOnce(const std::vector<Slice>& slices, size_t segments) {
  std::vector<int> seen(segments, 0);
  for (const Slice& s : slices) {
    EXPECT_FALSE(s.rows.empty());
    for (uint32_t r : s.rows) {
      ASSERT_LT(r, segments);
      ++seen[r];
    }
    for (uint32_t n : s.neighbors) EXPECT_LT(n, slices.size());
  }
  for (size_t i = 0; i < segments; ++i) ASSERT_EQ(seen[i], 1) << "segment " << i;
}

TEST(SegmentSimilarity, IdenticalSegmentsAreMaximallySimilar) {
  const SegmentSimilarityParams p{.B = 2.f, .kappa = 0.5f, .pixel_sigma = 4.f};
  const SegmentFeatures a = Feature({0, 0, 0}, {0.5f, 0, 0}, 0.4f, 0.7f, 10, 12);
  const SegmentSimilarityTerms t = SegmentSimilarity(a, a, p);
  EXPECT_FLOAT_EQ(t.spatial, 1.f);
  EXPECT_FLOAT_EQ(t.directional, 1.f);
  EXPECT_FLOAT_EQ(t.transmittance, 1.f);
  EXPECT_FLOAT_EQ(t.pixel, 1.f);
  EXPECT_FLOAT_EQ(t.Sum(), 4.f);
}

TEST(SegmentSimilarity, TermsFallAsTheEquationsSay) {
  const SegmentSimilarityParams p{.B = 2.f, .kappa = 0.5f, .pixel_sigma = 4.f};
  const SegmentFeatures a = Feature({0, 0, 0}, {0.5f, 0, 0}, 0.4f, 0.7f, 10, 12);
  // Eq. 10: S = (B − ‖Δx0‖ − ‖Δx1‖)/B; endpoints 0.5 apart each: (2 − 1)/2
  SegmentFeatures b = a;
  b.x0.y += 0.5f;
  b.x1.y += 0.5f;
  EXPECT_NEAR(SegmentSimilarity(a, b, p).spatial, 0.5f, 1e-6f);
  b.x0.y += 5.f;
  b.x1.y += 5.f;
  EXPECT_EQ(SegmentSimilarity(a, b, p).spatial, 0.f);  // farther than B: nothing
  // Eq. 11: opposite directions in a forward-scattering medium differ most; a perpendicular one
  // less; in an isotropic medium direction does not matter
  SegmentFeatures opposite = Feature({0.5f, 0, 0}, {0, 0, 0}, 0.4f, 0.7f, 10, 12);
  SegmentFeatures perpendicular = Feature({0, 0, 0}, {0, 0.5f, 0}, 0.4f, 0.7f, 10, 12);
  const float d_opp = SegmentSimilarity(a, opposite, p).directional;
  const float d_perp = SegmentSimilarity(a, perpendicular, p).directional;
  EXPECT_LT(d_opp, 0.1f);
  EXPECT_LT(d_opp, d_perp);
  EXPECT_LT(d_perp, 1.f);
  SegmentFeatures iso_a = a, iso_b = opposite;
  iso_a.g = iso_b.g = 0;
  EXPECT_FLOAT_EQ(SegmentSimilarity(iso_a, iso_b, p).directional, 1.f);
  // Segments of different media share no phase function
  SegmentFeatures other = a;
  other.medium = 1;
  EXPECT_EQ(SegmentSimilarity(a, other, p).directional, 0.f);
  // Eq. 12: T = 1 − |τi − τj|
  SegmentFeatures dense = a;
  dense.tau = 0.2f;
  EXPECT_NEAR(SegmentSimilarity(a, dense, p).transmittance, 0.5f, 1e-6f);
  // Pixel term: a Gaussian of the image distance
  SegmentFeatures far_pixel = a;
  far_pixel.px += 20;
  EXPECT_LT(SegmentSimilarity(a, far_pixel, p).pixel, 1e-6f);
  SegmentFeatures next_pixel = a;
  next_pixel.px += 1;
  EXPECT_NEAR(SegmentSimilarity(a, next_pixel, p).pixel, std::exp(-1.f / 8.f), 1e-6f);
  // Symmetric (the graph's edge weights do not depend on which end is asked)
  for (const SegmentFeatures& o : {b, opposite, perpendicular, dense, far_pixel})
    EXPECT_FLOAT_EQ(SegmentSimilarity(a, o, p).Sum(), SegmentSimilarity(o, a, p).Sum());
}

TEST(SegmentSlicing, SliceCountFollowsTheRaysWithinTheClamp) {
  SegmentSlicingOptions o;  // 500–1000 segments per slice
  EXPECT_EQ(SegmentSliceCount(0, 0, o), 0u);
  EXPECT_EQ(SegmentSliceCount(10, 1, o), 1u);
  // 0.008 × 100000 rays = 800 slices of 1000000 segments: 1250 each, above the clamp
  EXPECT_EQ(SegmentSliceCount(1000000, 100000, o), 1000u);
  // 0.008 × 100000 = 800 slices of 600000 segments: 750 each, inside
  EXPECT_EQ(SegmentSliceCount(600000, 100000, o), 800u);
  EXPECT_EQ(SegmentSliceCount(200000, 100000, o), 400u);  // 500 each: the lower end
}

TEST(SegmentSlicing, EverySegmentInExactlyOneSlice) {
  const std::unique_ptr<Scene> scene = FogScene(32);
  for (bool refine : {false, true}) {
    ReceiverSet receivers = FogReceivers(*scene);
    ASSERT_GT(receivers.segments.size(), 1500u);
    SegmentSlicingOptions o = SmallSlices();
    o.refine = refine;
    const std::vector<Slice> slices = SliceSegments(*scene, &receivers, o);
    EXPECT_GE(slices.size(), receivers.segments.size() / 300);
    ExpectEverySegmentOnce(slices, receivers.segments.size());
    for (size_t s = 0; s < slices.size(); ++s)
      for (uint32_t n : slices[s].neighbors) EXPECT_NE(n, s);
  }
}

TEST(SegmentSlicing, PartitionIsDeterministicWhateverTheThreadCount) {
  const std::unique_ptr<Scene> scene = FogScene(24);
  const ReceiverSet receivers = FogReceivers(*scene);
  const float diagonal = Length(scene->bounds().Diagonal());
  const SegmentSlicingOptions o = SmallSlices();
  std::vector<uint32_t> one, two, again;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    one = PartitionSegments(ComputeSegmentFeatures(*scene, receivers, 7), 6, diagonal, o);
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    two = PartitionSegments(ComputeSegmentFeatures(*scene, receivers, 7), 6, diagonal, o);
    again = PartitionSegments(ComputeSegmentFeatures(*scene, receivers, 7), 6, diagonal, o);
  }
  EXPECT_EQ(one, two);
  EXPECT_EQ(two, again);
  std::map<uint32_t, size_t> sizes;
  for (uint32_t p : one) ++sizes[p];
  EXPECT_EQ(sizes.size(), 6u);
  // METIS balances the parts (default imbalance 3%)
  for (const auto& [part, size] : sizes) EXPECT_GT(size, one.size() / 12) << part;
}

// Graph partitioning keeps rays together: consecutive segments of one ray share an endpoint and
// are linked, so most of them land in the same slice.
TEST(SegmentSlicing, ConsecutiveSegmentsOfARayMostlyShareASlice) {
  const std::unique_ptr<Scene> scene = FogScene(24);
  const ReceiverSet receivers = FogReceivers(*scene);
  const std::vector<uint32_t> part =
      PartitionSegments(ComputeSegmentFeatures(*scene, receivers, 7), 6,
                        Length(scene->bounds().Diagonal()), SmallSlices());
  size_t same = 0, pairs = 0;
  for (size_t s = 0; s + 1 < part.size(); ++s) {
    if (receivers.segments[s].sample != receivers.segments[s + 1].sample) continue;
    ++pairs;
    same += part[s] == part[s + 1];
  }
  ASSERT_GT(pairs, 400u);
  EXPECT_GT(double(same), 0.7 * double(pairs));
}

// Split and merge (threshold 2.5, and 0: split only) keep every ray's length, order and pieces
// contiguous; the segment count changes by splits − merges; with either boundary test, segments
// that run across a cut in depth are split.
class SegmentRefinement : public ::testing::TestWithParam<std::tuple<float, SegmentBoundary>> {};

TEST_P(SegmentRefinement, KeepsEachSamplesLengthAndContiguity) {
  const std::unique_ptr<Scene> scene = FogScene(24);
  const ReceiverSet before = FogReceivers(*scene);
  ReceiverSet after = before;
  const float diagonal = Length(scene->bounds().Diagonal());
  SegmentSlicingOptions o = SmallSlices();
  o.merge_threshold = std::get<0>(GetParam());
  o.boundary = std::get<1>(GetParam());
  std::vector<SegmentFeatures> features = ComputeSegmentFeatures(*scene, after, 7);
  // Three parts over the image, each cut in depth at z = 0 (the fog's centre plane): the rows
  // cut the fog's rays into segments of equal in-scattering weight, so METIS's parts alone rarely
  // run across a segment, and a depth cut gives both boundaries segments to split.
  std::vector<uint32_t> part = PartitionSegments(features, 3, diagonal, o);
  for (size_t k = 0; k < part.size(); ++k) part[k] += features[k].x0.z < 0 ? 3u : 0u;
  size_t merged = 0;
  const size_t splits = RefineSegmentSlices(*scene, &after, &features, &part, diagonal, o, &merged);
  EXPECT_GT(splits, 0u);
  if (o.merge_threshold > 0) {
    EXPECT_GT(merged, 0u);
  } else {
    EXPECT_EQ(merged, 0u);
  }
  ASSERT_EQ(after.segments.size(), before.segments.size() + splits - merged);
  ASSERT_EQ(part.size(), after.segments.size());
  ASSERT_EQ(features.size(), after.segments.size());
  for (uint32_t p : part) EXPECT_LT(p, 6u);
  ASSERT_EQ(after.samples.size(), before.samples.size());
  for (size_t i = 0; i < after.samples.size(); ++i) {
    const CameraSample& a = after.samples[i];
    const CameraSample& b = before.samples[i];
    double len_a = 0, len_b = 0;
    for (uint32_t k = 0; k < a.segment_count; ++k) {
      const EyeSegment& s = after.segments[size_t(a.first_segment) + k];
      ASSERT_EQ(s.sample, i);
      len_a += double(s.length);
      // contiguous along the ray: each segment starts where the previous one ends
      if (k > 0) {
        const EyeSegment& prev = after.segments[size_t(a.first_segment) + k - 1];
        EXPECT_LT(Distance(prev.o + prev.d * prev.length, s.o), 1e-3f);
      }
    }
    for (uint32_t k = 0; k < b.segment_count; ++k)
      len_b += double(before.segments[size_t(b.first_segment) + k].length);
    EXPECT_NEAR(len_a, len_b, 1e-4 * (1 + len_b)) << "sample " << i;
    if (o.merge_threshold == 0) {
      EXPECT_GE(a.segment_count, b.segment_count);
    }
  }
  // Merged features span their pieces: each starts where its segment starts and ends where it ends
  for (size_t k = 0; k < after.segments.size(); ++k) {
    const EyeSegment& seg = after.segments[k];
    EXPECT_LT(Distance(features[k].x0, seg.o), 1e-3f);
    EXPECT_LT(Distance(features[k].x1, seg.o + seg.d * seg.length), 1e-3f);
  }
}

INSTANTIATE_TEST_SUITE_P(MergeThresholdAndBoundary, SegmentRefinement,
                         ::testing::Combine(::testing::Values(2.5f, 0.f),
                                            ::testing::Values(SegmentBoundary::kHalves, SegmentBoundary::kSvm)));

// Nothing is as similar as 4 (the sum of four terms in [0, 1] for distinct pieces): no merges.
TEST(SegmentSlicing, MergeThresholdAboveTheLargestSimilarityNeverMerges) {
  const std::unique_ptr<Scene> scene = FogScene(24);
  ReceiverSet receivers = FogReceivers(*scene);
  const float diagonal = Length(scene->bounds().Diagonal());
  SegmentSlicingOptions o = SmallSlices();
  o.merge_threshold = 4.f;
  std::vector<SegmentFeatures> features = ComputeSegmentFeatures(*scene, receivers, 7);
  std::vector<uint32_t> part = PartitionSegments(features, 6, diagonal, o);
  size_t merged = 1;
  RefineSegmentSlices(*scene, &receivers, &features, &part, diagonal, o, &merged);
  EXPECT_EQ(merged, 0u);
}

// The RBF kernel separates what no plane can: points inside a sphere from a shell around it.
TEST(SvmBoundary, SeparatesASphereFromTheShellAroundIt) {
  Rng rng(5);
  const auto point_at = [&](float r_lo, float r_hi) {
    Vec3 d;
    do {
      d = Vec3(2 * rng.Uniform() - 1, 2 * rng.Uniform() - 1, 2 * rng.Uniform() - 1);
    } while (LengthSquared(d) > 1 || LengthSquared(d) < 1e-4f);
    return Normalize(d) * (r_lo + (r_hi - r_lo) * rng.Uniform()) + Vec3(3, -2, 7);
  };
  std::vector<Vec3> inside, outside;
  for (int i = 0; i < 300; ++i) {
    inside.push_back(point_at(0, 1));
    outside.push_back(point_at(1.6f, 2.2f));
  }
  const SvmBoundary svm(inside, outside, Vec3(3, -2, 7), 4.4f);
  ASSERT_TRUE(svm.valid());
  EXPECT_GT(svm.support_vectors(), 3u);
  int right = 0;
  for (int i = 0; i < 200; ++i) {
    right += svm.Decision(point_at(0, 0.9f)) > 0;
    right += svm.Decision(point_at(1.7f, 2.1f)) < 0;
  }
  EXPECT_GE(right, 392) << "of 400 held-out points";
  // Nothing to separate: no model, decision 0.
  const SvmBoundary empty(inside, {}, Vec3(0, 0, 0), 1.f);
  EXPECT_FALSE(empty.valid());
  EXPECT_EQ(empty.Decision(Vec3(3, -2, 7)), 0.0);
}

// The SVM refinement trains one boundary per pair of neighbouring slices in parallel: the same
// segments and slices whatever the thread count.
TEST(SegmentSlicing, SvmRefinementIsDeterministicWhateverTheThreadCount) {
  const std::unique_ptr<Scene> scene = FogScene(24);
  SegmentSlicingOptions o = SmallSlices();
  o.boundary = SegmentBoundary::kSvm;
  const auto slice = [&](int threads, std::vector<Slice>* slices) {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, size_t(threads));
    ReceiverSet receivers = FogReceivers(*scene);
    *slices = SliceSegments(*scene, &receivers, o);
    return receivers;
  };
  std::vector<Slice> one, two;
  const ReceiverSet a = slice(1, &one), b = slice(2, &two);
  ASSERT_EQ(a.segments.size(), b.segments.size());
  for (size_t s = 0; s < a.segments.size(); ++s) {
    EXPECT_EQ(a.segments[s].length, b.segments[s].length) << s;
    EXPECT_EQ(a.segments[s].throughput.g, b.segments[s].throughput.g) << s;
  }
  ASSERT_EQ(one.size(), two.size());
  for (size_t k = 0; k < one.size(); ++k) EXPECT_EQ(one[k].rows, two[k].rows) << k;
}

// A piece after a cut (at the middle, or wherever the SVM puts it) carries the transmittance of
// everything before it on its ray, as the receiver generator gives it: in the homogeneous fog,
// throughput(next) = throughput(prev) · exp(−σ_t · length(prev)) for every contiguous pair.
class SplitPieces : public ::testing::TestWithParam<SegmentBoundary> {};

TEST_P(SplitPieces, CarryTheTransmittanceBeforeTheirCut) {
  const std::unique_ptr<Scene> scene = FogScene(24);
  ReceiverSet receivers = FogReceivers(*scene);
  const size_t before = receivers.segments.size();
  SegmentSlicingOptions o = SmallSlices();
  o.boundary = GetParam();
  o.merge_threshold = 0;
  SliceSegments(*scene, &receivers, o);
  ASSERT_GT(receivers.segments.size(), before);
  const float sigma_t = 0.04f;
  size_t checked = 0;
  for (size_t s = 0; s + 1 < receivers.segments.size(); ++s) {
    const EyeSegment& a = receivers.segments[s];
    const EyeSegment& b = receivers.segments[s + 1];
    if (a.sample != b.sample || Distance(a.o + a.d * a.length, b.o) > 1e-3f) continue;
    EXPECT_NEAR(b.throughput.g, a.throughput.g * std::exp(-sigma_t * a.length), 1e-4f * a.throughput.g);
    ++checked;
  }
  EXPECT_GT(checked, 0u);
}

INSTANTIATE_TEST_SUITE_P(Boundary, SplitPieces, ::testing::Values(SegmentBoundary::kHalves, SegmentBoundary::kSvm));

}  // namespace test_segment_slicing
}  // namespace lightfarm
