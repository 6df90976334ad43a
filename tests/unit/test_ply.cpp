// PLY reader/writer: round trips, every supported type and layout, fan triangulation, and one
// test per way a file can be malformed (each must end in a SceneError naming the file).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "common/scene/ply.h"
#include "common/util/error.h"

namespace lightfarm {
namespace test_ply {

namespace fs = std::filesystem;

template <typename T>
void AppendBytes(std::string* out, T value, std::endian order) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if (order != std::endian::native) std::reverse(bytes, bytes + sizeof(T));
  out->append(bytes, sizeof(T));
}
template <typename T>
void AppendLE(std::string* out, T value) {
  AppendBytes(out, value, std::endian::little);
}
template <typename T>
void AppendBE(std::string* out, T value) {
  AppendBytes(out, value, std::endian::big);
}

// A small mesh with values that stress float round trips.
PlyMesh TwoTriangles(bool normals, bool uvs) {
  PlyMesh mesh;
  mesh.positions = {{0.1f, -2.5f, 3e-8f}, {1.f, 0.f, 0.f}, {1.f, 1.f, 1e30f}, {-0.f, 1.f, -7.f}};
  if (normals) mesh.normals = {{0, 0, 1}, {0, 1, 0}, {1, 0, 0}, {0.6f, 0.8f, 0.f}};
  if (uvs) mesh.uvs = {{0.f, 0.f}, {1.f, 0.f}, {1.f, 1.f}, {1.f / 3.f, 0.7f}};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  return mesh;
}

void ExpectSameMesh(const PlyMesh& a, const PlyMesh& b) {
  ASSERT_EQ(a.positions.size(), b.positions.size());
  ASSERT_EQ(a.normals.size(), b.normals.size());
  ASSERT_EQ(a.uvs.size(), b.uvs.size());
  for (size_t i = 0; i < a.positions.size(); ++i) EXPECT_EQ(a.positions[i], b.positions[i]) << i;
  for (size_t i = 0; i < a.normals.size(); ++i) EXPECT_EQ(a.normals[i], b.normals[i]) << i;
  for (size_t i = 0; i < a.uvs.size(); ++i) {
    EXPECT_EQ(a.uvs[i].x, b.uvs[i].x) << i;
    EXPECT_EQ(a.uvs[i].y, b.uvs[i].y) << i;
  }
  EXPECT_EQ(a.indices, b.indices);
}

class PlyTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("lightfarm_ply_" + std::to_string(::getpid()) + "_" + info->name());
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  std::string WriteBytes(const std::string& name, const std::string& bytes) const {
    std::string path = Path(name);
    std::ofstream(path, std::ios::binary) << bytes;
    return path;
  }

  // Reads bytes that must fail; checks the message, that it names the file, and the line.
  void ExpectError(const std::string& bytes, const std::string& expected, int line) const {
    std::string path = WriteBytes("bad.ply", bytes);
    try {
      ReadPly(path);
      ADD_FAILURE() << "no error; expected \"" << expected << "\"";
    } catch (const SceneError& e) {
      std::string what = e.what();
      EXPECT_NE(what.find(expected), std::string::npos) << what;
      EXPECT_EQ(what.rfind(path, 0), 0u) << what;
      EXPECT_EQ(e.loc().file, path);
      EXPECT_EQ(e.loc().line, line) << what;
    }
  }

  fs::path dir_;
};

// Header of an ASCII triangle soup with positions only.
std::string AsciiHeader(int vertices, int faces) {
  return "ply\nformat ascii 1.0\nelement vertex " + std::to_string(vertices) +
         "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
         std::to_string(faces) + "\nproperty list uchar int vertex_indices\nend_header\n";
}
const char* const kThreeVertices = "0 0 0\n1 0 0\n0 1 0\n";

// --- round trips --------------------------------------------------------------------------

TEST_F(PlyTest, AsciiRoundTripKeepsNormalsAndUvsExactly) {
  PlyMesh mesh = TwoTriangles(true, true);
  WritePly(Path("m.ply"), mesh, "ascii");
  ExpectSameMesh(ReadPly(Path("m.ply")), mesh);
}

TEST_F(PlyTest, BinaryRoundTripKeepsNormalsAndUvsExactly) {
  PlyMesh mesh = TwoTriangles(true, true);
  WritePly(Path("m.ply"), mesh, "binary_little_endian");
  ExpectSameMesh(ReadPly(Path("m.ply")), mesh);
  // 4 vertices of 8 floats and 2 faces of a uchar count and 3 ints follow the header
  std::ifstream in(Path("m.ply"), std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  size_t header_end = bytes.find("end_header\n") + std::strlen("end_header\n");
  EXPECT_EQ(bytes.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  EXPECT_EQ(bytes.size() - header_end, 4u * 8u * 4u + 2u * 13u);
}

TEST_F(PlyTest, RoundTripWithoutOptionalAttributes) {
  for (const char* format : {"ascii", "binary_little_endian"}) {
    PlyMesh mesh = TwoTriangles(false, false);
    WritePly(Path("m.ply"), mesh, format);
    PlyMesh read = ReadPly(Path("m.ply"));
    EXPECT_TRUE(read.normals.empty()) << format;
    EXPECT_TRUE(read.uvs.empty()) << format;
    ExpectSameMesh(read, mesh);
  }
}

TEST_F(PlyTest, WriterRejectsBadFormatAndInconsistentMesh) {
  PlyMesh mesh = TwoTriangles(true, false);
  EXPECT_THROW(WritePly(Path("m.ply"), mesh, "binary_big_endian"), SceneError);
  mesh.normals.pop_back();
  EXPECT_THROW(WritePly(Path("m.ply"), mesh, "ascii"), SceneError);
  mesh = TwoTriangles(false, false);
  mesh.indices.push_back(0);
  EXPECT_THROW(WritePly(Path("m.ply"), mesh, "ascii"), SceneError);
  mesh.indices = {0, 1, 4};
  EXPECT_THROW(WritePly(Path("m.ply"), mesh, "ascii"), SceneError);
}

// --- layouts ------------------------------------------------------------------------------

TEST_F(PlyTest, QuadAndPentagonAreFanTriangulated) {
  std::string bytes = AsciiHeader(5, 3) + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n-1 0.5 0\n" +
                      "4 0 1 2 3\n5 0 1 2 3 4\n3 4 3 2\n";
  PlyMesh mesh = ReadPly(WriteBytes("quad.ply", bytes));
  EXPECT_EQ(mesh.indices, (std::vector<int>{0, 1, 2, 0, 2, 3,           // quad
                                            0, 1, 2, 0, 2, 3, 0, 3, 4,  // pentagon
                                            4, 3, 2}));                 // triangle
}

TEST_F(PlyTest, ReadsHandBuiltBigEndianFileWithMixedTypes) {
  std::string bytes =
      "ply\nformat binary_big_endian 1.0\ncomment hand built\nobj_info test\n"
      "element vertex 3\n"
      "property double x\nproperty float y\nproperty int16 z\n"
      "property uchar red\nproperty list ushort float weights\n"
      "property float nx\nproperty float ny\nproperty float nz\n"
      "property float s\nproperty float t\n"
      "element edge 1\nproperty int vertex1\nproperty int vertex2\n"
      "element face 1\nproperty list ushort uint vertex_index\nproperty int face_indices\n"
      "end_header\n";
  for (int i = 0; i < 3; ++i) {
    AppendBE(&bytes, 1.5 * i);                         // x
    AppendBE(&bytes, -0.25f * static_cast<float>(i));  // y
    AppendBE(&bytes, static_cast<int16_t>(-300 + i));  // z
    AppendBE(&bytes, uint8_t{200});                    // red (skipped)
    AppendBE(&bytes, static_cast<uint16_t>(i));        // i weights (skipped)
    for (int w = 0; w < i; ++w) AppendBE(&bytes, 9.f);
    AppendBE(&bytes, 0.f);
    AppendBE(&bytes, 1.f);
    AppendBE(&bytes, 0.f);
    AppendBE(&bytes, 0.5f * static_cast<float>(i));  // s
    AppendBE(&bytes, 1.f);                           // t
  }
  AppendBE(&bytes, int32_t{0});  // edge
  AppendBE(&bytes, int32_t{2});
  AppendBE(&bytes, uint16_t{3});  // face
  for (uint32_t v : {2u, 1u, 0u}) AppendBE(&bytes, v);
  AppendBE(&bytes, int32_t{77});

  PlyMesh mesh = ReadPly(WriteBytes("be.ply", bytes));
  ASSERT_EQ(mesh.positions.size(), 3u);
  EXPECT_EQ(mesh.positions[2], Vec3(3.f, -0.5f, -298.f));
  EXPECT_EQ(mesh.normals[1], Vec3(0.f, 1.f, 0.f));
  EXPECT_EQ(mesh.uvs[2].x, 1.f);
  EXPECT_EQ(mesh.uvs[2].y, 1.f);
  EXPECT_EQ(mesh.indices, (std::vector<int>{2, 1, 0}));
}

// One file using every type name as a skipped vertex property, skipped lists and skipped
// elements before and after the mesh, written in each of the three formats.
std::string EveryTypeFile(const std::string& format) {
  const char* const kTypes[] = {"char",  "uchar",  "short",   "ushort", "int",   "uint",
                                "float", "double", "int8",    "uint8",  "int16", "uint16",
                                "int32", "uint32", "float32", "float64"};
  std::string header = "ply\nformat " + format + " 1.0\nelement material 2\n" +
                       "property list uint8 float64 colors\nproperty int16 id\n" +
                       "element vertex 4\n";
  for (int i = 0; i < 16; ++i) {
    header += std::string("property ") + kTypes[i] + " extra" + std::to_string(i) + "\n";
    if (i == 3) header += "property float x\nproperty float y\n";
    if (i == 9) header += "property list int32 int16 junk\nproperty double z\n";
  }
  header +=
      "element face 2\nproperty list uint16 uint8 face_indices\n"
      "property list int8 int16 vertex_indices\nproperty float quality\n"
      "element edge 1\nproperty list char uint32 pair\nend_header\n";
  if (format == "ascii") {
    std::string data = "2 0.5 0.25 7\n0 -7\n";
    for (int v = 0; v < 4; ++v) {
      data += "-1 2 -3 4 " + std::to_string(v) + " 0.5 -5 6 1e3 2.5 7 8 " + "2 -1 1 " +
              std::to_string(-v) + " -9 10 -11 12 3.5 -4.5 \n";
    }
    data += "1 9 4 0 1 2 3 0.5\n0 3 0 2 3 1\n2 5 6\n";
    return header + data;
  }
  std::endian order = format == "binary_big_endian" ? std::endian::big : std::endian::little;
  std::string data;
  auto put = [&](auto value) { AppendBytes(&data, value, order); };
  put(uint8_t{2}), put(0.5), put(0.25), put(int16_t{7});
  put(uint8_t{0}), put(int16_t{-7});
  for (int v = 0; v < 4; ++v) {
    put(int8_t{-1}), put(uint8_t{2}), put(int16_t{-3}), put(uint16_t{4});
    put(static_cast<float>(v)), put(0.5f);  // x y
    put(int32_t{-5}), put(uint32_t{6}), put(1e3f), put(2.5), put(int8_t{7}), put(uint8_t{8});
    put(int32_t{2}), put(int16_t{-1}), put(int16_t{1});  // junk list
    put(static_cast<double>(-v));                        // z
    put(int16_t{-9}), put(uint16_t{10}), put(int32_t{-11}), put(uint32_t{12}), put(3.5f), put(-4.5);
  }
  put(uint16_t{1}), put(uint8_t{9}), put(int8_t{4});
  for (int16_t i : {0, 1, 2, 3}) put(i);
  put(0.5f);
  put(uint16_t{0}), put(int8_t{3}), put(int16_t{0}), put(int16_t{2}), put(int16_t{3}), put(1.f);
  put(int8_t{2}), put(uint32_t{5}), put(uint32_t{6});
  return header + data;
}

TEST_F(PlyTest, SkipsUnknownPropertiesAndElementsOfEveryTypeInEveryFormat) {
  for (const char* format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    SCOPED_TRACE(format);
    PlyMesh mesh = ReadPly(WriteBytes("every.ply", EveryTypeFile(format)));
    ASSERT_EQ(mesh.positions.size(), 4u);
    for (int v = 0; v < 4; ++v)
      EXPECT_EQ(mesh.positions[v], Vec3(static_cast<float>(v), 0.5f, static_cast<float>(-v)));
    EXPECT_TRUE(mesh.normals.empty());
    EXPECT_TRUE(mesh.uvs.empty());
    EXPECT_EQ(mesh.indices, (std::vector<int>{0, 1, 2, 0, 2, 3, 0, 2, 3}));
  }
}

TEST_F(PlyTest, AcceptsAlternativeTextureCoordinateNamesAndCrlfHeaders) {
  for (const char* names : {"s t", "texture_u texture_v", "u v"}) {
    std::string u(names, std::strchr(names, ' ')), v(std::strchr(names, ' ') + 1);
    std::string bytes =
        "ply\r\nformat ascii 1.0\r\ncomment uv test\r\nelement vertex 3\r\n"
        "property float x\r\nproperty float y\r\nproperty float z\r\n"
        "property float " +
        u + "\r\nproperty float " + v +
        "\r\n"
        "element face 1\r\nproperty list uchar int vertex_indices\r\n"
        "end_header\r\n0 0 0 0.25 0.5\r\n1 0 0 1 0\r\n0 1 0 0 1\r\n3 0 1 2\r\n";
    PlyMesh mesh = ReadPly(WriteBytes("uv.ply", bytes));
    ASSERT_EQ(mesh.uvs.size(), 3u) << names;
    EXPECT_EQ(mesh.uvs[0].x, 0.25f) << names;
    EXPECT_EQ(mesh.uvs[0].y, 0.5f) << names;
  }
}

TEST_F(PlyTest, EmptyMeshIsValid) {
  PlyMesh mesh = ReadPly(WriteBytes("empty.ply", AsciiHeader(0, 0)));
  EXPECT_TRUE(mesh.positions.empty());
  EXPECT_TRUE(mesh.indices.empty());
}

// --- header errors ------------------------------------------------------------------------

TEST_F(PlyTest, MissingMagicFails) {
  ExpectError("plyx\nformat ascii 1.0\nend_header\n", "not a PLY file", 1);
  ExpectError("", "not a PLY file", 1);
  ExpectError("\x89PNG\r\n", "not a PLY file", 1);
}

TEST_F(PlyTest, UnknownFormatFails) {
  ExpectError("ply\nformat binary_middle_endian 1.0\nend_header\n", "unknown PLY format", 2);
  ExpectError("ply\nformat ascii 2.0\nend_header\n", "unsupported PLY version", 2);
  ExpectError("ply\nelement vertex 1\nend_header\n", "element before the format line", 2);
  ExpectError("ply\ncomment no format\nend_header\n", "no format line", 3);
}

TEST_F(PlyTest, UnknownTypeFails) {
  ExpectError("ply\nformat ascii 1.0\nelement vertex 1\nproperty flaot x\nend_header\n",
              "unknown property type \"flaot\"", 4);
  ExpectError("ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int64 vertex_indices\n",
              "unknown property type \"int64\"", 4);
  ExpectError("ply\nformat ascii 1.0\nelement face 1\nproperty list float int vertex_indices\n",
              "list count type \"float\" is not an integer type", 4);
}

TEST_F(PlyTest, MalformedHeaderLinesFail) {
  ExpectError("ply\nformat ascii 1.0\nelement vertex -3\nend_header\n", "bad element count", 3);
  ExpectError("ply\nformat ascii 1.0\nproperty float x\nend_header\n",
              "property before any element", 3);
  ExpectError("ply\nformat ascii 1.0\nelemnt vertex 3\nend_header\n", "unknown PLY header keyword",
              3);
  ExpectError("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", "no end_header line",
              4);
  ExpectError("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\n",
              "second property named \"x\"", 5);
}

TEST_F(PlyTest, MissingCoordinateFails) {
  for (const char* missing : {"x", "y", "z"}) {
    std::string bytes = "ply\nformat ascii 1.0\ncomment c\nelement vertex 1\n";
    for (const char* c : {"x", "y", "z"})
      if (std::strcmp(c, missing) != 0) bytes += std::string("property float ") + c + "\n";
    bytes += "element face 0\nproperty list uchar int vertex_indices\nend_header\n0 0\n";
    ExpectError(bytes, std::string("vertex element has no ") + missing + " property", 4);
  }
}

TEST_F(PlyTest, MissingMeshElementsOrPartialAttributesFail) {
  ExpectError(
      "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\n"
      "end_header\n",
      "no vertex element", 5);
  ExpectError(
      "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n",
      "no face element", 7);
  ExpectError(
      "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
      "property float z\nelement face 0\nproperty int vertex_indices\nend_header\n",
      "is not a list", 8);
  ExpectError(
      "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
      "property float z\nelement face 0\nproperty list uchar float vertex_indices\n"
      "end_header\n",
      "non-integer indices", 8);
  ExpectError(
      "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
      "property float z\nproperty float nx\nproperty float nz\nelement face 0\n"
      "property list uchar int vertex_indices\nend_header\n",
      "only some of the properties nx ny nz", 8);
}

TEST_F(PlyTest, HugeCountsInTinyFileFailBeforeAllocating) {
  auto start = std::chrono::steady_clock::now();
  // 4e9 vertices * 12 bytes would be a 48 GB allocation
  std::string binary_header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n";
  ExpectError(binary_header + std::string(1000, '\0'),
              "element \"vertex\" declares 4000000000 entries, but only 1000 bytes", 3);
  ExpectError(AsciiHeader(2000000000, 1) + kThreeVertices + "3 0 1 2\n",
              "declares 2000000000 entries", 3);
  std::string max_faces = AsciiHeader(3, 0);
  max_faces.replace(max_faces.find("face 0"), 6, "face 18446744073709551615");
  ExpectError(max_faces + kThreeVertices, "declares 18446744073709551615 entries", 7);
  std::string too_big = AsciiHeader(3, 0);
  too_big.replace(too_big.find("vertex 3"), 8, "vertex 18446744073709551616");
  ExpectError(too_big, "bad element count", 3);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(2));
}

// --- data errors --------------------------------------------------------------------------

TEST_F(PlyTest, TruncatedBinaryFails) {
  WritePly(Path("m.ply"), TwoTriangles(true, true), "binary_little_endian");
  std::ifstream in(Path("m.ply"), std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ExpectError(bytes.substr(0, bytes.size() - 1), "face 1: unexpected end of file", 0);
  // Cut inside the vertices: either check may catch it, but it must be a SceneError
  std::string cut = bytes.substr(0, bytes.find("end_header\n") + 11 + 40);
  EXPECT_THROW(ReadPly(WriteBytes("cut.ply", cut)), SceneError);
  ExpectError(bytes.substr(0, bytes.size() - 26 - 20), "declares 4 entries", 4);
}

TEST_F(PlyTest, TruncatedAsciiFails) {
  ExpectError(AsciiHeader(3, 2) + kThreeVertices + "3 0 1 2\n3 0 1\n",
              "face 1: unexpected end of file", 0);
  ExpectError(AsciiHeader(3, 1) + "0 0 0\n1 0 0\n0 1\n\n\n\n\n\n\n\n",
              "vertex 2: unexpected end of file", 0);
}

TEST_F(PlyTest, HeaderCountingTooFewElementsFails) {
  ExpectError(AsciiHeader(3, 1) + kThreeVertices + "3 0 1 2\n3 2 1 0\n",
              "unexpected data after the last element", 0);
  WritePly(Path("m.ply"), TwoTriangles(false, false), "binary_little_endian");
  std::ifstream in(Path("m.ply"), std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ExpectError(bytes + "x", "1 bytes of unexpected data", 0);
}

TEST_F(PlyTest, BadAsciiValueFails) {
  ExpectError(AsciiHeader(3, 1) + "0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n",
              "vertex 1: bad value \"zero\" for property \"y\"", 0);
  ExpectError(AsciiHeader(3, 1) + kThreeVertices + "300 0 1 2\n", "face 0: bad value \"300\"", 0);
}

TEST_F(PlyTest, FaceWithFewerThanThreeVerticesFails) {
  ExpectError(AsciiHeader(3, 2) + kThreeVertices + "3 0 1 2\n2 0 1\n", "face 1: has 2 vertices", 0);
}

TEST_F(PlyTest, OutOfRangeAndNegativeIndicesFail) {
  ExpectError(AsciiHeader(3, 2) + kThreeVertices + "3 0 1 2\n3 0 900 1\n",
              "face 1: vertex index 900 out of range (3 vertices)", 0);
  ExpectError(AsciiHeader(3, 1) + kThreeVertices + "3 0 -1 2\n",
              "face 0: vertex index -1 out of range", 0);
  // A uint32 index beyond INT_MAX must not wrap to a valid one
  std::string bytes =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
      "property float x\nproperty float y\nproperty float z\nelement face 1\n"
      "property list uchar uint vertex_indices\nend_header\n";
  for (int i = 0; i < 9; ++i) AppendLE(&bytes, 0.f);
  AppendLE(&bytes, uint8_t{3});
  for (uint32_t v : {0u, 1u, 4294967295u}) AppendLE(&bytes, v);
  ExpectError(bytes, "face 0: vertex index 4294967295 out of range", 0);
}

TEST_F(PlyTest, NegativeListLengthFails) {
  std::string bytes =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nproperty list char int junk\n"
      "element face 0\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0 0\n0 0 0 -4 1 2\n0 0 0 0\n";
  ExpectError(bytes, "vertex 1: negative list length -4", 0);
}

TEST_F(PlyTest, NonFinitePositionOrNormalFails) {
  ExpectError(AsciiHeader(3, 1) + "0 0 0\n1 0 0\n0 nan 0\n3 0 1 2\n",
              "vertex 2: non-finite position", 0);
  std::string normals =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nproperty float nx\n"
      "property float ny\nproperty float nz\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n";
  ExpectError(normals + "0 0 0 0 0 1\n1 0 0 0 0 -inf\n0 1 0 0 0 1\n3 0 1 2\n",
              "vertex 1: non-finite normal", 0);
  // A double too large for a float is as bad as an infinity
  std::string doubles =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\n"
      "property double x\nproperty double y\nproperty double z\n"
      "element face 0\nproperty list uchar int vertex_indices\nend_header\n";
  AppendLE(&doubles, 0.0);
  AppendLE(&doubles, 1e300);
  AppendLE(&doubles, 0.0);
  ExpectError(doubles, "vertex 0: non-finite position", 0);
  std::string nan_binary = AsciiHeader(1, 0);
  nan_binary.replace(nan_binary.find("ascii"), 5, "binary_little_endian");
  AppendLE(&nan_binary, 0.f);
  AppendLE(&nan_binary, 0.f);
  AppendLE(&nan_binary, std::numeric_limits<float>::quiet_NaN());
  ExpectError(nan_binary, "vertex 0: non-finite position", 0);
}

TEST_F(PlyTest, PolygonWithTooManyVerticesFails) {
  std::string ok = AsciiHeader(3, 1) + kThreeVertices + "64";
  for (int i = 0; i < 64; ++i) ok += " " + std::to_string(i % 3);
  EXPECT_EQ(ReadPly(WriteBytes("ok.ply", ok + "\n")).indices.size(), 62u * 3u);
  std::string bytes = AsciiHeader(3, 1) + kThreeVertices + "65";
  for (int i = 0; i < 65; ++i) bytes += " " + std::to_string(i % 3);
  ExpectError(bytes + "\n", "face 0: has 65 vertices (more than 64 allowed)", 0);
}

TEST_F(PlyTest, MissingFileFails) {
  EXPECT_THROW(ReadPly(Path("does_not_exist.ply")), SceneError);
  EXPECT_THROW(ReadPly(dir_.string()), SceneError);  // a directory
}

// --- the shared scene meshes --------------------------------------------------------------

fs::path SharedDir() {
  if (const char* env = std::getenv("LIGHTFARM_SHARED")) return env;
  return fs::path(LIGHTFARM_SOURCE_DIR) / ".." / "shared";
}

// The "element <name> N" count from a PLY header, read independently of the reader.
uint64_t HeaderCount(const fs::path& path, const std::string& element) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  while (std::getline(in, line) && line != "end_header") {
    std::istringstream words(line);
    std::string keyword, name;
    uint64_t count = 0;
    if (words >> keyword >> name >> count && keyword == "element" && name == element) return count;
  }
  return 0;
}

void ExpectIndicesInRange(const PlyMesh& mesh) {
  ASSERT_EQ(mesh.indices.size() % 3, 0u);
  int n = static_cast<int>(mesh.positions.size());
  EXPECT_TRUE(std::all_of(mesh.indices.begin(), mesh.indices.end(),
                          [n](int i) { return i >= 0 && i < n; }));
}

TEST(PlySharedMeshes, WaterCausticMeshesLoad) {
  fs::path models = SharedDir() / "scenes" / "water-caustic" / "models";
  ASSERT_TRUE(fs::is_directory(models))
      << "shared scene directory " << models
      << " is missing; set LIGHTFARM_SHARED to the shared data directory";

  // Mesh000: positions and uvs, all 513 faces triangles
  fs::path mesh000_path = models / "Mesh000.ply";
  PlyMesh mesh000 = ReadPly(mesh000_path.string());
  EXPECT_EQ(HeaderCount(mesh000_path, "vertex"), 519u);
  EXPECT_EQ(mesh000.positions.size(), 519u);
  EXPECT_EQ(mesh000.uvs.size(), 519u);
  EXPECT_TRUE(mesh000.normals.empty());
  EXPECT_EQ(HeaderCount(mesh000_path, "face"), 513u);
  EXPECT_EQ(mesh000.indices.size(), 513u * 3u);
  ExpectIndicesInRange(mesh000);

  // Mesh001: 3.3 MB with normals and uvs
  fs::path mesh001_path = models / "Mesh001.ply";
  PlyMesh mesh001 = ReadPly(mesh001_path.string());
  EXPECT_EQ(mesh001.positions.size(), HeaderCount(mesh001_path, "vertex"));
  EXPECT_EQ(mesh001.positions.size(), 63768u);
  EXPECT_EQ(mesh001.normals.size(), 63768u);
  EXPECT_EQ(mesh001.uvs.size(), 63768u);
  EXPECT_EQ(mesh001.indices.size(), 3u * HeaderCount(mesh001_path, "face"));
  EXPECT_EQ(mesh001.indices.size(), 3u * 102938u);
  ExpectIndicesInRange(mesh001);
  for (Vec3 n : mesh001.normals) ASSERT_NEAR(Length(n), 1.f, 1e-2f);
}

}  // namespace test_ply
}  // namespace lightfarm
