#include "common/render/serialize.h"

#include <bit>
#include <cstring>

namespace lightfarm {

namespace {

constexpr uint32_t kMagic = 0x3142464c;  // "LFB1" read as little-endian
enum class Kind : uint16_t { kLightSet = 1, kReceiverSet = 2, kTask = 3, kTaskOutput = 4 };

const char* KindName(Kind k) {
  switch (k) {
    case Kind::kLightSet: return "light set";
    case Kind::kReceiverSet: return "receiver set";
    case Kind::kTask: return "task";
    case Kind::kTaskOutput: return "task output";
  }
  return "?";
}

void WriteHeader(ByteWriter& w, Kind kind) {
  w.U32(kMagic);
  w.U16(uint16_t(kind));
  w.U16(kSerializeVersion);
}

void ReadHeader(ByteReader& r, Kind kind) {
  if (r.remaining() < 8)
    throw SerializeError(std::string(KindName(kind)) + ": input too short for a header");
  if (r.U32() != kMagic) throw SerializeError(std::string(KindName(kind)) + ": bad magic");
  uint16_t k = r.U16();
  if (k != uint16_t(kind))
    throw SerializeError(std::string("expected a ") + KindName(kind) + ", got kind " +
                         std::to_string(k));
  uint16_t v = r.U16();
  if (v != kSerializeVersion)
    throw SerializeError(std::string(KindName(kind)) + ": encoding version " + std::to_string(v) +
                         " is not supported (this build reads version " +
                         std::to_string(kSerializeVersion) + ")");
}

void PutVec3(ByteWriter& w, const Vec3& v) { w.F32(v.x); w.F32(v.y); w.F32(v.z); }
Vec3 GetVec3(ByteReader& r) { Vec3 v; v.x = r.F32(); v.y = r.F32(); v.z = r.F32(); return v; }
void PutRGB(ByteWriter& w, const RGB& c) { w.F32(c.r); w.F32(c.g); w.F32(c.b); }
RGB GetRGB(ByteReader& r) { RGB c; c.r = r.F32(); c.g = r.F32(); c.b = r.F32(); return c; }

void PutCounters(ByteWriter& w, const MatrixCounters& c) {
  w.U64(c.elements); w.U64(c.shadow_rays); w.F64(c.clamp_lost); w.F64(c.clamp_kept);
  w.U64(c.transmittance_evals);
  w.F64(c.clamp_compensated); w.U64(c.compensation_paths);
  w.F64(c.caustic_gathered); w.U64(c.caustic_photons_used);
  w.F64(c.bound_lost); w.U64(c.bound_elements);
}
MatrixCounters GetCounters(ByteReader& r) {
  MatrixCounters c;
  c.elements = r.U64(); c.shadow_rays = r.U64(); c.clamp_lost = r.F64(); c.clamp_kept = r.F64();
  c.transmittance_evals = r.U64();
  c.clamp_compensated = r.F64(); c.compensation_paths = r.U64();
  c.caustic_gathered = r.F64(); c.caustic_photons_used = r.U64();
  c.bound_lost = r.F64(); c.bound_elements = r.U64();
  return c;
}

void PutIndices(ByteWriter& w, const std::vector<uint32_t>& v) {
  w.U64(v.size());
  for (uint32_t x : v) w.U32(x);
}
std::vector<uint32_t> GetIndices(ByteReader& r) {
  std::vector<uint32_t> v(r.Count(4));
  for (uint32_t& x : v) x = r.U32();
  return v;
}

constexpr size_t kLightBytes = 4 * 3 * 5 + 4 + 1 + 1 + 1 + 1 + 4 + 4 + 1 + 4 + 2 + 4;
constexpr size_t kPointBytes = 4 * 3 * 5 + 4 + 4 + 1 + 2 + 2;
constexpr size_t kSampleBytes = 4 + 4 + 12 + 4 + 4 + 4 + 4;
constexpr size_t kSegmentBytes = 12 + 12 + 4 + 12 + 2 + 1 + 4 + 4 + 2;

}  // namespace

// --- primitives -------------------------------------------------------------------------------

void ByteWriter::U16(uint16_t v) { for (int i = 0; i < 2; ++i) out_.push_back(uint8_t(v >> (8 * i))); }
void ByteWriter::U32(uint32_t v) { for (int i = 0; i < 4; ++i) out_.push_back(uint8_t(v >> (8 * i))); }
void ByteWriter::U64(uint64_t v) { for (int i = 0; i < 8; ++i) out_.push_back(uint8_t(v >> (8 * i))); }
void ByteWriter::F32(float v) { U32(std::bit_cast<uint32_t>(v)); }
void ByteWriter::F64(double v) { U64(std::bit_cast<uint64_t>(v)); }
void ByteWriter::Str(const std::string& s) {
  U64(s.size());
  out_.insert(out_.end(), s.begin(), s.end());
}
void ByteWriter::Blob(ByteView b) {
  U64(b.size());
  out_.insert(out_.end(), b.begin(), b.end());
}

const uint8_t* ByteReader::Take(size_t n) {
  if (n > remaining())
    throw SerializeError("truncated input: need " + std::to_string(n) + " bytes at offset " +
                         std::to_string(pos_) + ", " + std::to_string(remaining()) + " left");
  const uint8_t* p = in_.data() + pos_;
  pos_ += n;
  return p;
}
uint8_t ByteReader::U8() { return *Take(1); }
uint16_t ByteReader::U16() {
  const uint8_t* p = Take(2);
  return uint16_t(p[0] | (p[1] << 8));
}
uint32_t ByteReader::U32() {
  const uint8_t* p = Take(4);
  uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
uint64_t ByteReader::U64() {
  const uint8_t* p = Take(8);
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
float ByteReader::F32() { return std::bit_cast<float>(U32()); }
double ByteReader::F64() { return std::bit_cast<double>(U64()); }
bool ByteReader::Bool() {
  uint8_t b = U8();
  if (b > 1) throw SerializeError("invalid boolean value " + std::to_string(b));
  return b != 0;
}
size_t ByteReader::Count(size_t min_item_bytes) {
  uint64_t n = U64();
  if (min_item_bytes > 0 && n > remaining() / min_item_bytes)
    throw SerializeError("count " + std::to_string(n) + " exceeds the remaining input");
  return size_t(n);
}
std::string ByteReader::Str() {
  size_t n = Count(1);
  const uint8_t* p = Take(n);
  return std::string(reinterpret_cast<const char*>(p), n);
}
Bytes ByteReader::Blob() {
  size_t n = Count(1);
  const uint8_t* p = Take(n);
  return Bytes(p, p + n);
}
void ByteReader::ExpectEnd() const {
  if (remaining() != 0)
    throw SerializeError(std::to_string(remaining()) + " unexpected trailing bytes");
}

// --- LightSet ---------------------------------------------------------------------------------

Bytes SerializeLightSet(const LightSet& set) {
  ByteWriter w;
  WriteHeader(w, Kind::kLightSet);
  const LightSetStats& s = set.stats;
  for (size_t v : {s.area_vpls, s.surface_vpls, s.point_lights, s.directional_lights,
                   s.particle_paths, s.caustic_vpls, s.glossy_vpls, s.medium_vpls, s.vrls, s.vrl_flights})
    w.U64(v);
  w.U64(set.lights.size());
  for (const VirtualLight& l : set.lights) {
    PutVec3(w, l.p); PutVec3(w, l.n); PutVec3(w, l.ng); PutVec3(w, l.wi);
    PutRGB(w, l.power);
    w.U32(l.material);
    w.U8(uint8_t(l.kind));
    w.U8(l.depth);
    w.U8(l.two_sided);
    w.U8(l.caustic);
    w.F32(l.cos_falloff_start);
    w.F32(l.cos_falloff_end);
    w.U8(l.spot);
    w.F32(l.g);
    w.U16(uint16_t(l.medium));
    w.F32(l.length);
  }
  return w.Take();
}

LightSet DeserializeLightSet(ByteView bytes) {
  ByteReader r(bytes);
  ReadHeader(r, Kind::kLightSet);
  LightSet set;
  LightSetStats& s = set.stats;
  for (size_t* v : {&s.area_vpls, &s.surface_vpls, &s.point_lights, &s.directional_lights,
                    &s.particle_paths, &s.caustic_vpls, &s.glossy_vpls, &s.medium_vpls, &s.vrls, &s.vrl_flights})
    *v = size_t(r.U64());
  set.lights.resize(r.Count(kLightBytes));
  for (VirtualLight& l : set.lights) {
    l.p = GetVec3(r); l.n = GetVec3(r); l.ng = GetVec3(r); l.wi = GetVec3(r);
    l.power = GetRGB(r);
    l.material = r.U32();
    uint8_t kind = r.U8();
    if (kind > uint8_t(VirtualLightKind::kVRL))
      throw SerializeError("light set: invalid light kind " + std::to_string(kind));
    l.kind = VirtualLightKind(kind);
    l.depth = r.U8();
    l.two_sided = r.Bool();
    l.caustic = r.Bool();
    l.cos_falloff_start = r.F32();
    l.cos_falloff_end = r.F32();
    l.spot = r.Bool();
    l.g = r.F32();
    l.medium = int16_t(r.U16());
    l.length = r.F32();
  }
  r.ExpectEnd();
  return set;
}

// --- ReceiverSet ------------------------------------------------------------------------------

Bytes SerializeReceiverSet(const ReceiverSet& set) {
  ByteWriter w;
  WriteHeader(w, Kind::kReceiverSet);
  w.U32(uint32_t(set.width));
  w.U32(uint32_t(set.height));
  w.U32(uint32_t(set.spp));
  for (size_t v : {set.stats.camera_rays, set.stats.specular_bounces, set.stats.escaped,
                   set.stats.nonfinite_rays, set.stats.camera_paths, set.stats.camera_pilot_paths,
                   set.stats.camera_active_pixels, set.stats.media_direct_samples, set.stats.split_vertices,
                   set.stats.near_sharp_vertices, set.stats.coverage_paths, set.stats.segment_coverage})
    w.U64(v);
  w.U64(set.samples.size());
  for (const CameraSample& c : set.samples) {
    w.U32(c.pixel);
    w.F32(c.weight);
    PutRGB(w, c.emitted);
    w.U32(uint32_t(c.first_point));
    w.U32(c.point_count);
    w.U32(uint32_t(c.first_segment));
    w.U32(c.segment_count);
  }
  w.U64(set.points.size());
  for (const ShadingPoint& p : set.points) {
    PutVec3(w, p.p); PutVec3(w, p.ng); PutVec3(w, p.ns); PutVec3(w, p.wo);
    PutRGB(w, p.throughput);
    w.U32(p.material);
    w.U32(p.sample);
    w.U8(p.depth);
    w.U16(uint16_t(p.medium_out));
    w.U16(uint16_t(p.medium_in));
  }
  for (const std::vector<EyeSegment>* segments : {&set.segments, &set.segment_pieces}) {
    w.U64(segments->size());
    for (const EyeSegment& e : *segments) {
      PutVec3(w, e.o); PutVec3(w, e.d);
      w.F32(e.length);
      PutRGB(w, e.throughput);
      w.U16(uint16_t(e.medium));
      w.U8(e.depth);
      w.U32(e.sample);
      w.U32(e.first_piece);
      w.U16(e.pieces);
    }
  }
  return w.Take();
}

ReceiverSet DeserializeReceiverSet(ByteView bytes) {
  ByteReader r(bytes);
  ReadHeader(r, Kind::kReceiverSet);
  ReceiverSet set;
  uint32_t width = r.U32(), height = r.U32(), spp = r.U32();
  if (width > (1u << 20) || height > (1u << 20) || spp > (1u << 20))
    throw SerializeError("receiver set: implausible size " + std::to_string(width) + "x" +
                         std::to_string(height) + " spp " + std::to_string(spp));
  set.width = int(width);
  set.height = int(height);
  set.spp = int(spp);
  for (size_t* v : {&set.stats.camera_rays, &set.stats.specular_bounces, &set.stats.escaped,
                    &set.stats.nonfinite_rays, &set.stats.camera_paths, &set.stats.camera_pilot_paths,
                    &set.stats.camera_active_pixels, &set.stats.media_direct_samples, &set.stats.split_vertices,
                    &set.stats.near_sharp_vertices, &set.stats.coverage_paths, &set.stats.segment_coverage})
    *v = size_t(r.U64());
  const uint64_t pixels = uint64_t(width) * height;
  set.samples.resize(r.Count(kSampleBytes));
  std::vector<int32_t> sample_points;
  for (CameraSample& c : set.samples) {
    c.pixel = r.U32();
    c.weight = r.F32();
    c.emitted = GetRGB(r);
    c.first_point = int32_t(r.U32());
    c.point_count = r.U32();
    c.first_segment = int32_t(r.U32());
    c.segment_count = r.U32();
    if (c.pixel >= pixels)
      throw SerializeError("receiver set: sample pixel " + std::to_string(c.pixel) +
                           " outside the image");
  }
  set.points.resize(r.Count(kPointBytes));
  for (ShadingPoint& p : set.points) {
    p.p = GetVec3(r); p.ng = GetVec3(r); p.ns = GetVec3(r); p.wo = GetVec3(r);
    p.throughput = GetRGB(r);
    p.material = r.U32();
    p.sample = r.U32();
    p.depth = r.U8();
    p.medium_out = int16_t(r.U16());
    p.medium_in = int16_t(r.U16());
    if (p.sample >= set.samples.size())
      throw SerializeError("receiver set: shading point names sample " + std::to_string(p.sample) +
                           " of " + std::to_string(set.samples.size()));
  }
  for (std::vector<EyeSegment>* segments : {&set.segments, &set.segment_pieces}) {
    segments->resize(r.Count(kSegmentBytes));
    for (EyeSegment& e : *segments) {
      e.o = GetVec3(r); e.d = GetVec3(r);
      e.length = r.F32();
      e.throughput = GetRGB(r);
      e.medium = int16_t(r.U16());
      e.depth = r.U8();
      e.sample = r.U32();
      e.first_piece = r.U32();
      e.pieces = r.U16();
      if (e.sample >= set.samples.size())
        throw SerializeError("receiver set: eye segment names sample " + std::to_string(e.sample) +
                             " of " + std::to_string(set.samples.size()));
    }
  }
  for (const EyeSegment& e : set.segments)
    if (e.pieces > 0 && uint64_t(e.first_piece) + e.pieces > set.segment_pieces.size())
      throw SerializeError("receiver set: eye segment names coverage pieces out of range");
  for (const EyeSegment& e : set.segment_pieces)
    if (e.pieces > 0) throw SerializeError("receiver set: a coverage piece has pieces of its own");
  for (const CameraSample& c : set.samples) {
    if (c.point_count > 0 &&
        (c.first_point < 0 || size_t(c.first_point) + c.point_count > set.points.size()))
      throw SerializeError("receiver set: sample names shading points " + std::to_string(c.first_point) + "+" +
                           std::to_string(c.point_count) + " of " + std::to_string(set.points.size()));
    if (c.segment_count > 0 &&
        (c.first_segment < 0 || size_t(c.first_segment) + c.segment_count > set.segments.size()))
      throw SerializeError("receiver set: sample names eye segments out of range");
  }
  r.ExpectEnd();
  return set;
}

// --- SubMatrixTask ----------------------------------------------------------------------------

Bytes SerializeTask(const SubMatrixTask& task) {
  ByteWriter w;
  WriteHeader(w, Kind::kTask);
  w.U32(task.stage);
  w.U32(task.task_id);
  w.U64(task.seed);
  PutIndices(w, task.rows);
  PutIndices(w, task.neighbors);
  w.U32(task.sample_begin);
  w.U32(task.sample_end);
  return w.Take();
}

SubMatrixTask DeserializeTask(ByteView bytes) {
  ByteReader r(bytes);
  ReadHeader(r, Kind::kTask);
  SubMatrixTask task;
  task.stage = r.U32();
  task.task_id = r.U32();
  task.seed = r.U64();
  task.rows = GetIndices(r);
  task.neighbors = GetIndices(r);
  task.sample_begin = r.U32();
  task.sample_end = r.U32();
  if (task.sample_end < task.sample_begin) throw SerializeError("task: sample range ends before it begins");
  r.ExpectEnd();
  return task;
}

// --- TaskOutput -------------------------------------------------------------------------------

Bytes SerializeTaskOutput(const TaskOutput& out) {
  ByteWriter w;
  WriteHeader(w, Kind::kTaskOutput);
  w.U64(out.row_sums.size());
  for (const RGBAccum& s : out.row_sums) { w.F64(s.r); w.F64(s.g); w.F64(s.b); }
  w.U64(out.row_weights.size());
  for (double v : out.row_weights) w.F64(v);
  w.Blob(out.payload);
  PutCounters(w, out.counters);
  w.U64(out.stats.size());
  for (const auto& [k, v] : out.stats) { w.Str(k); w.F64(v); }
  return w.Take();
}

TaskOutput DeserializeTaskOutput(ByteView bytes) {
  ByteReader r(bytes);
  ReadHeader(r, Kind::kTaskOutput);
  TaskOutput out;
  out.row_sums.resize(r.Count(24));
  for (RGBAccum& s : out.row_sums) { s.r = r.F64(); s.g = r.F64(); s.b = r.F64(); }
  out.row_weights.resize(r.Count(8));
  for (double& v : out.row_weights) v = r.F64();
  if (!out.row_weights.empty() && out.row_weights.size() != out.row_sums.size())
    throw SerializeError("task output: " + std::to_string(out.row_weights.size()) + " row weights for " +
                         std::to_string(out.row_sums.size()) + " rows");
  out.payload = r.Blob();
  out.counters = GetCounters(r);
  size_t n = r.Count(16);
  for (size_t i = 0; i < n; ++i) {
    std::string key = r.Str();
    double v = r.F64();
    if (!out.stats.emplace(key, v).second)
      throw SerializeError("task output: repeated stats key \"" + key + "\"");
  }
  r.ExpectEnd();
  return out;
}

}  // namespace lightfarm
