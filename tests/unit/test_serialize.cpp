// The farm's binary encodings (common/render/serialize.h): exact round trips (bit-for-bit floats,
// which farm/embedded identity relies on) and rejection of malformed bytes without crashing.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "common/render/serialize.h"

namespace lightfarm {
namespace test_serialize {

LightSet SampleLights() {
  LightSet set;
  set.stats.area_vpls = 1;
  set.stats.surface_vpls = 1;
  set.stats.point_lights = 1;
  set.stats.particle_paths = 77;
  VirtualLight a;
  a.p = Vec3(1.5f, -2.25f, 1e-30f);
  a.n = Vec3(0, 1, 0);
  a.ng = Vec3(0, 0.7071f, 0.7071f);
  a.power = RGB(0.1f, 0.2f, std::numeric_limits<float>::denorm_min());
  a.kind = VirtualLightKind::kAreaVPL;
  a.two_sided = true;
  VirtualLight b;
  b.kind = VirtualLightKind::kSurfaceVPL;
  b.material = 12;
  b.depth = 3;
  b.caustic = true;
  b.wi = Vec3(-0.f, 1, 0);
  VirtualLight c;
  c.kind = VirtualLightKind::kPoint;
  c.spot = true;
  c.cos_falloff_start = 0.9f;
  c.cos_falloff_end = 0.8f;
  set.lights = {a, b, c};
  return set;
}

ReceiverSet SampleReceivers() {
  ReceiverSet r;
  r.width = 2;
  r.height = 1;
  r.spp = 2;
  r.stats.camera_rays = 4;
  r.stats.escaped = 1;
  r.stats.coverage_paths = 45;
  for (uint32_t s = 0; s < 4; ++s) {
    CameraSample cs;
    cs.pixel = s / 2;
    cs.weight = 0.25f * float(s + 1);
    cs.emitted = RGB(float(s));
    // Sample 0 has point 0; sample 1 points 1 and 2 (a split vertex and the end of its path);
    // samples 2 and 3 none.
    if (s < 2) {
      cs.first_point = int32_t(s);
      cs.point_count = s + 1;
    }
    r.samples.push_back(cs);
  }
  for (uint32_t i = 0; i < 3; ++i) {
    ShadingPoint p;
    p.p = Vec3(float(i), 2, 3);
    p.throughput = RGB(0.5f);
    p.material = i;
    p.sample = std::min(i, 1u);
    p.depth = uint8_t(i + 1);
    r.points.push_back(p);
  }
  return r;
}

bool SameBits(float a, float b) { return std::bit_cast<uint32_t>(a) == std::bit_cast<uint32_t>(b); }
bool SameBits(const Vec3& a, const Vec3& b) { return SameBits(a.x, b.x) && SameBits(a.y, b.y) && SameBits(a.z, b.z); }
bool SameBits(const RGB& a, const RGB& b) { return SameBits(a.r, b.r) && SameBits(a.g, b.g) && SameBits(a.b, b.b); }

TEST(Serialize, LightSetRoundTripIsBitExact) {
  LightSet in = SampleLights();
  LightSet out = DeserializeLightSet(SerializeLightSet(in));
  ASSERT_EQ(out.size(), in.size());
  EXPECT_EQ(out.stats.particle_paths, 77u);
  EXPECT_EQ(out.stats.point_lights, 1u);
  for (size_t i = 0; i < in.size(); ++i) {
    const VirtualLight &x = in.lights[i], &y = out.lights[i];
    EXPECT_TRUE(SameBits(x.p, y.p) && SameBits(x.n, y.n) && SameBits(x.ng, y.ng) && SameBits(x.wi, y.wi)) << i;
    EXPECT_TRUE(SameBits(x.power, y.power)) << i;
    EXPECT_EQ(x.kind, y.kind);
    EXPECT_EQ(x.material, y.material);
    EXPECT_EQ(x.depth, y.depth);
    EXPECT_EQ(x.two_sided, y.two_sided);
    EXPECT_EQ(x.caustic, y.caustic);
    EXPECT_EQ(x.spot, y.spot);
    EXPECT_TRUE(SameBits(x.cos_falloff_start, y.cos_falloff_start));
    EXPECT_TRUE(SameBits(x.cos_falloff_end, y.cos_falloff_end));
  }
  // -0 keeps its sign (bit-exact, not just equal).
  EXPECT_TRUE(std::signbit(out.lights[1].wi.x));
}

TEST(Serialize, ReceiverSetRoundTrip) {
  ReceiverSet in = SampleReceivers();
  ReceiverSet out = DeserializeReceiverSet(SerializeReceiverSet(in));
  EXPECT_EQ(out.width, 2);
  EXPECT_EQ(out.height, 1);
  EXPECT_EQ(out.spp, 2);
  EXPECT_EQ(out.stats.escaped, 1u);
  EXPECT_EQ(out.stats.coverage_paths, 45u);
  ASSERT_EQ(out.samples.size(), 4u);
  ASSERT_EQ(out.points.size(), 3u);
  EXPECT_EQ(out.samples[3].first_point, -1);
  EXPECT_EQ(out.samples[3].point_count, 0u);
  EXPECT_EQ(out.samples[1].first_point, 1);
  EXPECT_EQ(out.samples[1].point_count, 2u);
  EXPECT_TRUE(SameBits(out.samples[2].weight, 0.75f));
  EXPECT_EQ(out.points[2].depth, 3);
  EXPECT_TRUE(SameBits(out.points[1].p, Vec3(1, 2, 3)));
}

// Eye segments and their coverage pieces (EyeSegment::pieces) cross the wire whole; a segment
// that names pieces past the end, or a piece that has pieces of its own, is refused.
TEST(Serialize, EyeSegmentsAndCoveragePiecesRoundTrip) {
  ReceiverSet in = SampleReceivers();
  in.stats.segment_coverage = 16;
  EyeSegment seg;
  seg.o = Vec3(1, 2, 3);
  seg.d = Vec3(0, 0, -1);
  seg.length = 2.5f;
  seg.throughput = RGB(0.25f);
  seg.medium = 1;
  seg.sample = 2;
  seg.first_piece = 1;
  seg.pieces = 2;
  in.samples[2].first_segment = 0;
  in.samples[2].segment_count = 1;
  in.segments = {seg};
  EyeSegment piece = seg;
  piece.first_piece = 0;
  piece.pieces = 0;
  in.segment_pieces = {piece, piece, piece};
  in.segment_pieces[2].length = 1.75f;
  const ReceiverSet out = DeserializeReceiverSet(SerializeReceiverSet(in));
  EXPECT_EQ(out.stats.segment_coverage, 16u);
  ASSERT_EQ(out.segments.size(), 1u);
  ASSERT_EQ(out.segment_pieces.size(), 3u);
  EXPECT_EQ(out.segments[0].first_piece, 1u);
  EXPECT_EQ(out.segments[0].pieces, 2);
  EXPECT_TRUE(SameBits(out.segments[0].o, seg.o));
  EXPECT_TRUE(SameBits(out.segment_pieces[2].length, 1.75f));
  EXPECT_EQ(out.segment_pieces[1].medium, 1);

  ReceiverSet past_end = in;
  past_end.segments[0].first_piece = 2;
  EXPECT_THROW(DeserializeReceiverSet(SerializeReceiverSet(past_end)), SerializeError);
  ReceiverSet nested = in;
  nested.segment_pieces[0].pieces = 1;
  EXPECT_THROW(DeserializeReceiverSet(SerializeReceiverSet(nested)), SerializeError);
}

TEST(Serialize, TaskAndOutputRoundTrip) {
  SubMatrixTask t;
  t.stage = 2;
  t.task_id = 9;
  t.seed = 0xfeedfacecafebeefULL;
  t.rows = {5, 6, 7, 4000000000u};
  t.neighbors = {1, 3};
  SubMatrixTask t2 = DeserializeTask(SerializeTask(t));
  EXPECT_EQ(t2.stage, 2u);
  EXPECT_EQ(t2.task_id, 9u);
  EXPECT_EQ(t2.seed, t.seed);
  EXPECT_EQ(t2.rows, t.rows);
  EXPECT_EQ(t2.neighbors, t.neighbors);

  TaskOutput o;
  o.row_sums = {RGBAccum{0.1, 0.2, 1e300}, RGBAccum{-0.0, 5e-324, 3}};
  o.payload = {1, 2, 3, 0, 255};
  o.counters.elements = 123;
  o.counters.shadow_rays = 45;
  o.counters.clamp_lost = 0.125;
  o.stats = {{"clusters", 7.5}, {"x", -1}};
  TaskOutput o2 = DeserializeTaskOutput(SerializeTaskOutput(o));
  ASSERT_EQ(o2.row_sums.size(), 2u);
  EXPECT_EQ(std::bit_cast<uint64_t>(o2.row_sums[0].b), std::bit_cast<uint64_t>(1e300));
  EXPECT_EQ(std::bit_cast<uint64_t>(o2.row_sums[1].g), std::bit_cast<uint64_t>(5e-324));
  EXPECT_TRUE(std::signbit(o2.row_sums[1].r));
  EXPECT_EQ(o2.payload, o.payload);
  EXPECT_EQ(o2.counters.elements, 123u);
  EXPECT_EQ(o2.counters.shadow_rays, 45u);
  EXPECT_EQ(o2.counters.clamp_lost, 0.125);
  EXPECT_EQ(o2.stats, o.stats);
}

TEST(Serialize, EncodingIsLittleEndianWithHeader) {
  SubMatrixTask t;
  t.task_id = 0x01020304;
  Bytes b = SerializeTask(t);
  ASSERT_GE(b.size(), 16u);
  EXPECT_EQ(std::string(b.begin(), b.begin() + 4), "LFB1");
  EXPECT_EQ(b[6], kSerializeVersion & 0xff);
  // stage (4 bytes) then task id, least significant byte first.
  EXPECT_EQ(b[12], 0x04);
  EXPECT_EQ(b[15], 0x01);
}

TEST(Serialize, RejectsWrongKindVersionAndTrailingBytes) {
  Bytes lights = SerializeLightSet(SampleLights());
  EXPECT_THROW(DeserializeReceiverSet(lights), SerializeError);
  EXPECT_THROW(DeserializeTask(lights), SerializeError);
  Bytes v = lights;
  v[6] = uint8_t(kSerializeVersion + 1);
  try {
    DeserializeLightSet(v);
    FAIL() << "a future version was accepted";
  } catch (const SerializeError& e) {
    EXPECT_NE(std::string(e.what()).find("version"), std::string::npos) << e.what();
  }
  Bytes trailing = lights;
  trailing.push_back(0);
  EXPECT_THROW(DeserializeLightSet(trailing), SerializeError);
  EXPECT_THROW(DeserializeLightSet(Bytes{}), SerializeError);
}

TEST(Serialize, RejectsInvalidEnumsBoolsAndIndices) {
  LightSet set = SampleLights();
  Bytes b = SerializeLightSet(set);
  // The kind byte of the first light: header 8 + stats 80 + count 8 + 5 vectors (60) + material 4.
  const size_t kind_at = 8 + 80 + 8 + 60 + 4;
  ASSERT_EQ(b[kind_at], uint8_t(VirtualLightKind::kAreaVPL));
  Bytes bad_kind = b;
  bad_kind[kind_at] = 9;
  EXPECT_THROW(DeserializeLightSet(bad_kind), SerializeError);
  Bytes bad_bool = b;
  bad_bool[kind_at + 2] = 2;  // two_sided
  EXPECT_THROW(DeserializeLightSet(bad_bool), SerializeError);

  ReceiverSet r = SampleReceivers();
  r.samples[0].first_point = 17;  // no such shading point
  EXPECT_THROW(DeserializeReceiverSet(SerializeReceiverSet(r)), SerializeError);
  r = SampleReceivers();
  r.samples[1].point_count = 3;  // runs past the last shading point
  EXPECT_THROW(DeserializeReceiverSet(SerializeReceiverSet(r)), SerializeError);
  r = SampleReceivers();
  r.samples[1].pixel = 99;  // outside a 2x1 image
  EXPECT_THROW(DeserializeReceiverSet(SerializeReceiverSet(r)), SerializeError);
}

TEST(Serialize, HugeCountsAreRejectedBeforeAllocating) {
  SubMatrixTask t;
  Bytes b = SerializeTask(t);
  // The rows count sits after header (8) + stage, task (8) + seed (8).
  for (int i = 0; i < 8; ++i) b[24 + size_t(i)] = 0xff;
  EXPECT_THROW(DeserializeTask(b), SerializeError);
}

TEST(Serialize, EveryTruncationAndRandomCorruptionFailsCleanly) {
  const std::vector<Bytes> inputs = {SerializeLightSet(SampleLights()), SerializeReceiverSet(SampleReceivers()),
                                     SerializeTaskOutput(TaskOutput{{RGBAccum{1, 2, 3}}, {0.5}, {9, 9}, {}, {{"k", 1}}})};
  for (size_t which = 0; which < inputs.size(); ++which) {
    const Bytes& full = inputs[which];
    auto decode = [which](ByteView v) {
      if (which == 0) DeserializeLightSet(v);
      else if (which == 1) DeserializeReceiverSet(v);
      else DeserializeTaskOutput(v);
    };
    for (size_t n = 0; n < full.size(); ++n)
      EXPECT_THROW(decode(ByteView(full.data(), n)), SerializeError) << "input " << which << " cut at " << n;
    std::mt19937 rng(42 + unsigned(which));
    for (int trial = 0; trial < 300; ++trial) {
      Bytes b = full;
      b[rng() % b.size()] ^= uint8_t(1 + rng() % 255);
      try {
        decode(b);  // a flipped float bit is still a valid encoding: either outcome is fine
      } catch (const SerializeError&) {
      }
    }
  }
}

}  // namespace test_serialize
}  // namespace lightfarm
