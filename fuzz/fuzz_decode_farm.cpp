// libFuzzer target: the farm's binary decoders (common/render/serialize.h) on arbitrary bytes.
// Each must either decode or throw SerializeError; whatever decodes must survive a round trip:
// its encoding decodes to a value with the same encoding. (The input itself may differ from that
// encoding: TaskOutput's stats are a map, so keys in another order decode to the same value.)
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "common/render/serialize.h"

namespace {

template <typename Decode, typename Encode>
void RoundTrip(lightfarm::ByteView bytes, Decode decode, Encode encode) {
  try {
    const lightfarm::Bytes once = encode(decode(bytes));
    const lightfarm::Bytes twice = encode(decode(once));
    if (once != twice) std::abort();
  } catch (const lightfarm::SerializeError&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace lightfarm;
  const ByteView bytes(data, size);
  RoundTrip(bytes, DeserializeTask, SerializeTask);
  RoundTrip(bytes, DeserializeTaskOutput, SerializeTaskOutput);
  RoundTrip(bytes, DeserializeLightSet, SerializeLightSet);
  RoundTrip(bytes, DeserializeReceiverSet, SerializeReceiverSet);
  return 0;
}
