// Versioned little-endian binary encodings of the data the farm moves between processes: the
// light set and receiver set of a plan (content-addressed blobs), a SubMatrixTask (in a lease)
// and a TaskOutput (a worker's result). No networking here: the coordinator and the worker put
// these bytes into protobuf `bytes` fields or blobs.
//
// Every encoding starts with a header (magic "LFB1", kind, version); decoding checks the header,
// every length against the bytes left and every enum/bool value, so malformed or truncated input
// throws SerializeError and never reads out of bounds or allocates more than the input implies.
#pragma once

#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/gather/gather.h"
#include "common/lights/virtual_light.h"
#include "common/receivers/receivers.h"

namespace lightfarm {

class SerializeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

using Bytes = std::vector<uint8_t>;
using ByteView = std::span<const uint8_t>;

// Bumped whenever an encoding below changes; a decoder refuses other versions.
// 2: media on shading points, medium VPLs; 3: VRLs (light length, VRL count); 4: film methods
// (task sample range, row weights); 5: caustic counters; 6: camera-side paths (receiver stats); 7: element-bound counters;
// 8: VRL flights and camera-side single-scattering samples (light set and receiver stats);
// 9: several shading points per camera sample (split mixed vertices); 10: coverage paths
// (receiver stats)
inline constexpr uint16_t kSerializeVersion = 12;

Bytes SerializeLightSet(const LightSet& lights);
LightSet DeserializeLightSet(ByteView bytes);

Bytes SerializeReceiverSet(const ReceiverSet& receivers);
ReceiverSet DeserializeReceiverSet(ByteView bytes);

Bytes SerializeTask(const SubMatrixTask& task);
SubMatrixTask DeserializeTask(ByteView bytes);

Bytes SerializeTaskOutput(const TaskOutput& output);
TaskOutput DeserializeTaskOutput(ByteView bytes);

// Little-endian primitive writer/reader, exposed for other farm encodings and tests.
class ByteWriter {
 public:
  void U8(uint8_t v) { out_.push_back(v); }
  void U16(uint16_t v);
  void U32(uint32_t v);
  void U64(uint64_t v);
  void F32(float v);
  void F64(double v);
  void Str(const std::string& s);
  void Blob(ByteView b);
  Bytes Take() { return std::move(out_); }

 private:
  Bytes out_;
};

class ByteReader {
 public:
  explicit ByteReader(ByteView in) : in_(in) {}
  uint8_t U8();
  uint16_t U16();
  uint32_t U32();
  uint64_t U64();
  float F32();
  double F64();
  bool Bool();
  std::string Str();
  Bytes Blob();
  // A count of items each at least `min_item_bytes` long: rejects counts the input cannot hold.
  size_t Count(size_t min_item_bytes);
  size_t remaining() const { return in_.size() - pos_; }
  void ExpectEnd() const;

 private:
  const uint8_t* Take(size_t n);
  ByteView in_;
  size_t pos_ = 0;
};

}  // namespace lightfarm
