// Bad input through the real `lightfarm` binary: malformed scenes and PLY files, and every option
// of every subcommand. Each ends with a non-zero exit code, one line on stderr (naming file:line
// for scene problems), no crash, and no output file left behind.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "common/scene/ply.h"
#include "tests/stability/stability_util.h"

namespace lightfarm {
namespace test_bad_input_cli {

using testing::CliResult;
using testing::LineCount;
using testing::RunCli;
using testing::kQuad;
using testing::TempDir;
namespace fs = std::filesystem;

const std::string kHead =
    "Film \"rgb\" \"integer xresolution\" [8] \"integer yresolution\" [8]\n"
    "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\nWorldBegin\n"
    "LightSource \"point\" \"rgb I\" [5 5 5] \"point3 from\" [0 0 3]\n";  // 5 lines
// Renders `scene` (a path) and checks the failure contract; `where` must appear in the message.
void ExpectRenderFails(const TempDir& dir, const std::string& scene, const std::string& where,
                       const std::string& label) {
  const std::string out = dir.Path("out/img.exr");
  const CliResult r = RunCli(dir, "render " + scene + " --lights 10 --quiet --out " + out +
                                      " --stats " + dir.Path("out/img.json"));
  EXPECT_NE(r.exit_code, 0) << label;
  EXPECT_FALSE(r.signalled) << label << ": " << r.err;
  EXPECT_EQ(LineCount(r.err), 1u) << label << ": " << r.err;
  EXPECT_NE(r.err.find(where), std::string::npos) << label << ": " << r.err;
  EXPECT_EQ(r.err.find("Assertion"), std::string::npos) << label;
  // Nothing at all in out/: no image, no stats, no temporary file.
  const fs::path out_dir = dir.Path("out");
  if (fs::exists(out_dir))
    for (const fs::directory_entry& e : fs::directory_iterator(out_dir))
      ADD_FAILURE() << label << " left " << e.path().filename();
}

TEST(BadSceneInput, EveryMalformedSceneFailsWithFileAndLine) {
  TempDir dir;
  struct Case {
    std::string label, world, where;
  };
  dir.Write("loop_a.pbrt", "# a\nInclude \"loop_b.pbrt\"\n");
  dir.Write("loop_b.pbrt", "\nInclude \"loop_a.pbrt\"\n");
  const std::vector<Case> cases = {
      {"unknown directive", "Frobnicate 1 2 3\n", "s.pbrt:6:"},
      {"wrong parameter type", "Shape \"sphere\" \"string radius\" \"one\"\n", "s.pbrt:6:"},
      {"wrong value type", "Shape \"sphere\" \"float radius\" \"one\"\n", "s.pbrt:6:"},
      {"wrong count", "AreaLightSource \"diffuse\" \"rgb L\" [1 2]\n" + kQuad, "s.pbrt:6:"},
      {"too few arguments", "Translate 1 2\n", "s.pbrt:"},
      {"missing include", "\nInclude \"nope.pbrt\"\n", "s.pbrt:7:"},
      {"missing ply", "Shape \"plymesh\" \"string filename\" \"nope.ply\"\n", "s.pbrt:6:"},
      {"unterminated string", "Shape \"sphere\n", "s.pbrt:6:"},
      {"recursive include", "Include \"loop_a.pbrt\"\n", "loop_b.pbrt:2:"},
      {"huge number", "Shape \"sphere\" \"float radius\" [1e39]\n", "s.pbrt:6:"},
      {"huger number", "Translate 1e999 0 0\n", "s.pbrt:6:"},
      {"huge integer", "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]"
                       " \"integer indices\" [0 1 99999999999999999999]\n", "s.pbrt:6:"},
      {"index out of range", "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]"
                             " \"integer indices\" [0 1 3]\n", "s.pbrt:6:"},
      {"unknown shape", "Shape \"teapot\"\n", "s.pbrt:6:"},
      {"unknown material", "NamedMaterial \"nope\"\n" + kQuad, "s.pbrt:6:"},
      {"unbalanced block", "AttributeBegin\n" + kQuad, "s.pbrt:6:"},
      {"unused parameter", "Shape \"sphere\" \"float radiuss\" [1]\n", "s.pbrt:6:"},
      {"binary garbage", std::string("\x01\x02\xff\xfe\x00zz", 7), "s.pbrt:"},
  };
  for (const Case& c : cases) {
    const std::string scene = dir.Write("s.pbrt", kHead + c.world);
    ExpectRenderFails(dir, scene, c.where, c.label);
  }
}

TEST(BadSceneInput, TruncatedOrLyingPlyHeadersFailWithTheFileName) {
  TempDir dir;
  PlyMesh mesh;
  mesh.positions = {Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0), Vec3(-1, 1, 0)};
  mesh.normals.assign(4, Vec3(0, 0, 1));
  mesh.indices = {0, 1, 2, 0, 2, 3};
  WritePly(dir.Path("good_bin.ply"), mesh, "binary_little_endian");
  WritePly(dir.Path("good_ascii.ply"), mesh, "ascii");
  const std::string bin = testing::Slurp(dir.Path("good_bin.ply"));
  const std::string ascii = testing::Slurp(dir.Path("good_ascii.ply"));
  auto replace = [](std::string s, const std::string& from, const std::string& to) {
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) s.replace(at, from.size(), to);
    return s;
  };
  const std::vector<std::pair<std::string, std::string>> plys = {
      {"truncated binary", bin.substr(0, bin.size() - 7)},
      {"truncated header", bin.substr(0, bin.find("end_header") + 3)},
      {"truncated ascii", ascii.substr(0, ascii.size() - 6)},
      {"lying vertex count", replace(bin, "element vertex 4", "element vertex 4000000")},
      {"lying face count", replace(ascii, "element face 2", "element face 3")},
      {"lying format", replace(ascii, "format ascii 1.0", "format binary_little_endian 1.0")},
      {"binary claimed ascii", replace(bin, "format binary_little_endian 1.0", "format ascii 1.0")},
      {"huge count", replace(ascii, "element vertex 4", "element vertex 99999999999999999999")},
      {"negative count", replace(ascii, "element vertex 4", "element vertex -4")},
      {"empty file", ""},
  };
  for (const auto& [label, bytes] : plys) {
    {
      std::ofstream f(dir.Path("bad.ply"), std::ios::binary | std::ios::trunc);
      f.write(bytes.data(), std::streamsize(bytes.size()));
    }
    const std::string scene =
        dir.Write("s.pbrt", kHead + "Shape \"plymesh\" \"string filename\" \"bad.ply\"\n");
    ExpectRenderFails(dir, scene, "bad.ply", label);
  }
  // The untouched files render (the cases above fail for their defect only).
  const std::string scene =
      dir.Write("ok.pbrt", kHead + "Shape \"plymesh\" \"string filename\" \"good_bin.ply\"\n");
  EXPECT_EQ(RunCli(dir, "render " + scene + " --lights 10 --quiet --out " + dir.Path("ok.exr")).exit_code, 0);
}

// Every option of every subcommand with a bad value: exit code != 0 and a single line.
TEST(CliOptions, EveryBadOptionIsOneLine) {
  TempDir dir;
  const std::string scene = dir.Write("tiny.pbrt", kHead + kQuad);
  const std::string img = dir.Path("img.exr");
  ASSERT_EQ(RunCli(dir, "render " + scene + " --lights 10 --quiet --out " + img).exit_code, 0);
  const std::string r = "render " + scene + " --quiet --out " + dir.Path("o/x.exr") + " ";
  // The farm commands get an address nothing listens on and a short timeout: the option
  // checks must fire before any connection is tried.
  const std::string server = " --server 127.0.0.1:1 --timeout 2";
  const std::vector<std::string> bad = {
      "", "frobnicate", "render", "--bogus",
      r + "--resolution 12", r + "--resolution 0x5", r + "--resolution 10x",
      r + "--resolution -3x4", r + "--resolution 99999999x1", r + "--resolution axb",
      r + "--resolution 70000x70000", r + "--spp -1", r + "--spp 0", r + "--spp abc",
      r + "--spp 1e9", r + "--lights 0", r + "--lights -3", r + "--lights 1e99",
      r + "--lights 99999999999999999999", r + "--method nope", r + "--method ''",
      r + "--param clamp", r + "--param =1", r + "--param nosuch=1", r + "--param clamp=abc",
      r + "--param clamp=-1", r + "--param clamp=nan", r + "--param clamp=inf",
      r + "--param rows_per_slice=0", r + "--param direct_fraction=2",
      r + "--method mrcs --param rows=0", r + "--method mrcs --param rows=x",
      r + "--method lightcuts --param error=-1", r + "--method sparse-completion --param rank=0",
      r + "--filter nope", r + "--threads -1", r + "--threads x", r + "--workers 0",
      r + "--workers 100000", r + "--seed -1", r + "--seed x", r + "--out x.png",
      "render " + scene + " --quiet --out ''", "render /no/such/file.pbrt",
      "render " + dir.Path(""), "render " + scene + " --quiet --out " + img + " --stats /proc/x/y.json",
      "compare", "compare " + img, "compare /no/such.exr " + img, "compare " + img + " " + scene,
      "compare " + img + " " + img + " --heatmap x.jpg",
      "compare " + img + " " + img + " --heatmap-max 0",
      "compare " + img + " " + img + " --heatmap-max -1",
      "compare " + img + " " + img + " --heatmap-max abc",
      "compare " + img + " " + img + " --heatmap-max nan",
      "submit " + scene, "submit " + scene + server + " --out x.exr",
      "submit " + scene + server + " --spp 0", "submit " + scene + server + " --priority x",
      "submit " + scene + server + " --resolution 1x", "submit /no/such.pbrt" + server,
      "submit " + scene + " --server 127.0.0.1:1 --timeout 0",
      "submit " + scene + " --server 127.0.0.1:1 --timeout -5",
      "status --server", "status --server 127.0.0.1:1 --timeout x",
      "watch", "watch --server 127.0.0.1:1", "watch job1 --server 127.0.0.1:1 --timeout -1",
      "cancel", "cancel job1", "cancel job1" + server + " --tls-ca /no/such.pem",
      "fetch", "fetch job1", "fetch job1" + server + " --out x.png",
      "status" + server + " --token-file /no/such/token",
  };
  for (const std::string& args : bad) {
    const CliResult res = RunCli(dir, args);
    EXPECT_NE(res.exit_code, 0) << args;
    EXPECT_FALSE(res.signalled) << args << "\n" << res.err;
    EXPECT_EQ(LineCount(res.err), 1u) << args << "\n" << res.err;
  }
  EXPECT_FALSE(fs::exists(dir.Path("o/x.exr")));
}

}  // namespace test_bad_input_cli
}  // namespace lightfarm

namespace lightfarm {
namespace test_bad_input_cli {

// Regression: an unwritable --stats used to fail after the EXR and PNG were written, leaving
// a result that looked complete.
TEST(BadOutput, UnwritableStatsLeavesNoImageBehind) {
  testing::TempDir dir;
  const std::string scene = dir.Write("tiny.pbrt", kHead + kQuad);
  const testing::CliResult r =
      testing::RunCli(dir, "render " + scene + " --lights 10 --quiet --out " +
                               dir.Path("o/img.exr") + " --stats /proc/no/such/stats.json");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(testing::LineCount(r.err), 1u) << r.err;
  EXPECT_FALSE(fs::exists(dir.Path("o/img.exr")));
  EXPECT_FALSE(fs::exists(dir.Path("o/img.png")));
  // A --stats directory that does not exist yet is created, like --out's.
  const testing::CliResult ok =
      testing::RunCli(dir, "render " + scene + " --lights 10 --quiet --out " +
                               dir.Path("o/img.exr") + " --stats " + dir.Path("s/new/img.json"));
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_TRUE(fs::exists(dir.Path("s/new/img.json")));
}

}  // namespace test_bad_input_cli
}  // namespace lightfarm
