// The `lightfarm` binary as a user runs it: exit codes, one-line errors, outputs on disk.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_cli {

using testing::kTinyScene;
using testing::TempDir;

struct CommandResult {
  int exit_code = -1;
  std::string out, err;
};

// `env`: VAR=value assignments for the command's environment.
CommandResult RunCli(const TempDir& dir, const std::string& args, const std::string& env = "") {
  std::string out = dir.Path("stdout.txt"), err = dir.Path("stderr.txt");
  std::string cmd = (env.empty() ? "" : "env " + env + " ") + std::string(LIGHTFARM_CLI_PATH) + " " +
                    args + " >" + out + " 2>" + err;
  int status = std::system(cmd.c_str());
  CommandResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  auto slurp = [](const std::string& p) {
    std::ifstream f(p);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
  };
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

size_t Lines(const std::string& s) { return size_t(std::count(s.begin(), s.end(), '\n')); }

TEST(Cli, RenderWritesExrPngAndStats) {
  TempDir dir;
  std::string scene = dir.Write("tiny.pbrt", kTinyScene);
  CommandResult r = RunCli(dir, "render " + scene + " --lights 10 --out " + dir.Path("o/img.exr") +
                                 " --stats " + dir.Path("o/img.json") + " --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(std::filesystem::exists(dir.Path("o/img.exr")));
  EXPECT_TRUE(std::filesystem::exists(dir.Path("o/img.png")));
  std::ifstream f(dir.Path("o/img.json"));
  nlohmann::json stats = nlohmann::json::parse(f);
  EXPECT_EQ(stats["method"], "brute");
  EXPECT_EQ(stats["resolution"][0], 8);
}

// OpenImageIO is a module loaded when an image is read or written (common/image/image_io_backend.h).
TEST(Cli, TheImageModuleLoadsOnlyForImagesAndItsAbsenceFailsBeforeRendering) {
  TempDir dir;
  const std::string missing = dir.Path("no-such-module.so");
  const std::string env = "LIGHTFARM_IMAGEIO_MODULE=" + missing;
  CommandResult version = RunCli(dir, "--version", env);
  EXPECT_EQ(version.exit_code, 0) << version.err;
  EXPECT_EQ(version.out, std::string(LIGHTFARM_VERSION) + "\n");

  std::string scene = dir.Write("tiny.pbrt", kTinyScene);
  CommandResult r = RunCli(dir, "render " + scene + " --lights 10 --out " + dir.Path("img.exr"), env);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(Lines(r.err), 1u) << r.err;
  EXPECT_NE(r.err.find("liblightfarm_imageio.so"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(missing + ": no such file"), std::string::npos) << r.err;
  // It failed before rendering: no progress was shown and nothing was written.
  EXPECT_EQ(r.err.find("lights"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir.Path("img.exr")));
  EXPECT_FALSE(std::filesystem::exists(dir.Path("img.png")));
}

TEST(Cli, MalformedSceneGivesOneLineWithFileAndLineAndNoOutput) {
  TempDir dir;
  std::string scene = dir.Write("bad.pbrt", std::string(kTinyScene) + "Shape \"sphere\" \"float radius\" [1\n");
  CommandResult r = RunCli(dir, "render " + scene + " --out " + dir.Path("bad.exr") + " --quiet");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(Lines(r.err), 1u) << r.err;
  EXPECT_NE(r.err.find("bad.pbrt:"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir.Path("bad.exr")));
  EXPECT_FALSE(std::filesystem::exists(dir.Path("bad.png")));
}

TEST(Cli, InvalidOptionsAreRejectedWithOneLine) {
  TempDir dir;
  std::string scene = dir.Write("tiny.pbrt", kTinyScene);
 for (const std::string& args : std::vector<std::string>{
        "render " + scene + " --resolution 12", "render " + scene + " --spp 0",
        "render " + scene + " --lights -3", "render " + scene + " --method nope",
        "render " + scene + " --param clamp", "render " + scene + " --param nosuch=1",
        "render " + scene + " --out x.png", "render /no/such/file.pbrt", "frobnicate"}) {
    CommandResult r = RunCli(dir, args);
    EXPECT_NE(r.exit_code, 0) << args;
    EXPECT_EQ(Lines(r.err), 1u) << args << "\n" << r.err;
  }
}

TEST(Cli, CompareReportsMetricsAndJson) {
  TempDir dir;
  std::string scene = dir.Write("tiny.pbrt", kTinyScene);
  ASSERT_EQ(RunCli(dir, "render " + scene + " --lights 10 --out " + dir.Path("a.exr") + " --quiet").exit_code, 0);
  CommandResult same = RunCli(dir, "compare " + dir.Path("a.exr") + " " + dir.Path("a.exr"));
  ASSERT_EQ(same.exit_code, 0) << same.err;
  EXPECT_EQ(same.out.rfind("rel_l2=0  rel_l1=0  rmse=0", 0), 0u) << same.out;
  CommandResult js = RunCli(dir, "compare --json " + dir.Path("a.exr") + " " + dir.Path("a.exr"));
  ASSERT_EQ(js.exit_code, 0);
  nlohmann::json j = nlohmann::json::parse(js.out);
  EXPECT_EQ(j["rel_l2"], 0.0);
  // Different sizes need --resize.
  ASSERT_EQ(RunCli(dir, "render " + scene + " --lights 10 --resolution 4x4 --out " + dir.Path("b.exr") + " --quiet").exit_code, 0);
  CommandResult diff = RunCli(dir, "compare " + dir.Path("a.exr") + " " + dir.Path("b.exr"));
  EXPECT_NE(diff.exit_code, 0);
  EXPECT_NE(diff.err.find("--resize"), std::string::npos);
  EXPECT_EQ(RunCli(dir, "compare --resize " + dir.Path("a.exr") + " " + dir.Path("b.exr")).exit_code, 0);
}

}  // namespace test_cli
}  // namespace lightfarm
