// Every input kept under fuzz/regressions/TARGET/ (found by scripts/fuzz.sh) run through the same
// checks as the fuzz target, in the ordinary (and sanitizer) test build: the parser and the PLY
// reader either succeed or throw SceneError; the farm decoders either throw SerializeError or
// round-trip. Plus the property each kept input was about.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "common/render/serialize.h"
#include "common/scene/ply.h"
#include "common/scene/scene_description.h"
#include "common/util/error.h"
#include "tests/stability/stability_util.h"

namespace lightfarm {
namespace test_fuzz_regressions {

namespace fs = std::filesystem;

std::vector<std::string> Inputs(const std::string& target) {
  std::vector<std::string> out;
  const fs::path dir = testing::SourcePath("fuzz/regressions/" + target);
  if (fs::is_directory(dir))
    for (const auto& entry : fs::directory_iterator(dir))
      if (entry.is_regular_file()) out.push_back(entry.path().string());
  return out;
}

// The contract every scene input meets: it parses (into shapes whose materials exist), or it fails with a SceneError that names the
// file and a line ("fuzz.pbrt:LINE: what is wrong"), never another exception.
TEST(FuzzRegressions, ParseScene) {
  testing::TempDir empty;
  const std::vector<std::string> inputs = Inputs("parse_scene");
  EXPECT_FALSE(inputs.empty());
  for (const std::string& path : inputs) {
    try {
      const SceneDescription scene = ParseSceneString(testing::Slurp(path), "fuzz.pbrt", empty.Path(""));
      for (const ShapeDesc& shape : scene.shapes)
        EXPECT_TRUE(shape.material >= -1 && shape.material < int(scene.materials.size())) << path;
    } catch (const SceneError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("fuzz.pbrt:", 0), 0u) << path << ": " << e.what();
    }
  }
}

// Every PLY input is read into a valid triangle mesh (indices in range, a multiple of three) or
// refused with a SceneError naming the file. The kept inputs are hand-made malformed files
// (a truncated binary body, a missing end_header, an index out of range, a vertex count that
// overflows) and a quad that must become two triangles.
TEST(FuzzRegressions, ReadPly) {
  const std::vector<std::string> inputs = Inputs("read_ply");
  EXPECT_GE(inputs.size(), 5u);
  int read = 0, refused = 0;
  for (const std::string& path : inputs) {
    const std::string name = fs::path(path).filename().string();
    try {
      const PlyMesh mesh = ReadPly(path);
      ++read;
      EXPECT_EQ(mesh.indices.size() % 3, 0u) << path;
      for (int i : mesh.indices) EXPECT_LT(size_t(i), mesh.positions.size()) << path;
      if (name == "quad_is_two_triangles.ply") {
        EXPECT_EQ(mesh.indices.size(), 6u);
      }
    } catch (const SceneError& e) {
      ++refused;
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
      EXPECT_NE(name, "quad_is_two_triangles.ply") << e.what();
    }
  }
  EXPECT_GE(read, 1);
  EXPECT_GE(refused, 4);
}

template <typename Decode, typename Encode>
void ExpectStableRoundTrip(const Bytes& bytes, Decode decode, Encode encode, const std::string& what) {
  try {
    const Bytes once = encode(decode(ByteView(bytes)));
    EXPECT_EQ(once, encode(decode(ByteView(once)))) << what;
  } catch (const SerializeError&) {
  }
}

TEST(FuzzRegressions, DecodeFarm) {
  const std::vector<std::string> inputs = Inputs("decode_farm");
  EXPECT_FALSE(inputs.empty());
  for (const std::string& path : inputs) {
    const std::string text = testing::Slurp(path);
    const Bytes bytes(text.begin(), text.end());
    ExpectStableRoundTrip(bytes, DeserializeTask, SerializeTask, path);
    ExpectStableRoundTrip(bytes, DeserializeTaskOutput, SerializeTaskOutput, path);
    ExpectStableRoundTrip(bytes, DeserializeLightSet, SerializeLightSet, path);
    ExpectStableRoundTrip(bytes, DeserializeReceiverSet, SerializeReceiverSet, path);
  }
}

// The fuzzer's find (fuzz/regressions/decode_farm, an encoding-version-1 input kept for the
// corpus): stats keys out of order decode to the same sorted map, so a re-encoding differs from
// the input but is stable. Built here in the current encoding: the stats section is last, as a
// count followed by (key, value) entries, so two one-key outputs give the entries to swap.
TEST(FuzzRegressions, TaskOutputWithUnsortedStatsKeysDecodesToTheSortedMap) {
  auto encode = [](std::map<std::string, double> stats) {
    TaskOutput out;
    out.row_sums = {RGBAccum{1, 2, 3}};
    out.counters.elements = 7;
    out.stats = std::move(stats);
    return SerializeTaskOutput(out);
  };
  const Bytes none = encode({}), a = encode({{"a", 1.0}}), b = encode({{"b", 2.0}});
  const size_t prefix = none.size() - 8;  // everything before the stats count (a u64)
  ASSERT_EQ(Bytes(a.begin(), a.begin() + long(prefix)), Bytes(none.begin(), none.begin() + long(prefix)));
  ASSERT_EQ(a[prefix], 1);
  Bytes unsorted(none.begin(), none.begin() + long(prefix));
  Bytes count(a.begin() + long(prefix), a.begin() + long(prefix) + 8);
  count[0] = 2;
  unsorted.insert(unsorted.end(), count.begin(), count.end());
  unsorted.insert(unsorted.end(), b.begin() + long(prefix) + 8, b.end());  // "b" first
  unsorted.insert(unsorted.end(), a.begin() + long(prefix) + 8, a.end());
  const TaskOutput out = DeserializeTaskOutput(ByteView(unsorted));
  EXPECT_EQ(out.stats, (std::map<std::string, double>{{"a", 1.0}, {"b", 2.0}}));
  EXPECT_NE(SerializeTaskOutput(out), unsorted);
  EXPECT_EQ(SerializeTaskOutput(out), encode({{"a", 1.0}, {"b", 2.0}}));
  EXPECT_EQ(SerializeTaskOutput(DeserializeTaskOutput(ByteView(SerializeTaskOutput(out)))),
            SerializeTaskOutput(out));
}

}  // namespace test_fuzz_regressions
}  // namespace lightfarm
