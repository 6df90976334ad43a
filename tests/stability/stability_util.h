// Helpers of the stability suite: finite/bounded checks, the real `lightfarm` binary, and small
// scenes built from text.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include "common/image/image.h"
#include "common/scene/scene.h"
#include "common/scene/scene_description.h"
#include "tests/common/test_util.h"

namespace lightfarm::testing {

struct CliResult {
  int exit_code = -1;
  bool signalled = false;  // killed by a signal (a crash)
  std::string out, err;
};

inline std::string Slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// Runs `lightfarm ARGS` (the build's binary) through the shell; stdout/stderr land in `dir`.
inline CliResult RunCli(const TempDir& dir, const std::string& args) {
  const std::string out = dir.Path("cli-stdout.txt"), err = dir.Path("cli-stderr.txt");
  const std::string cmd =
      std::string(LIGHTFARM_CLI_PATH) + " " + args + " >" + out + " 2>" + err + " </dev/null";
  const int status = std::system(cmd.c_str());
  CliResult r;
  r.signalled = WIFSIGNALED(status) || (WIFEXITED(status) && WEXITSTATUS(status) >= 128);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = Slurp(out);
  r.err = Slurp(err);
  return r;
}

inline size_t LineCount(const std::string& s) { return size_t(std::count(s.begin(), s.end(), '\n')); }

inline std::unique_ptr<Scene> BuildSceneFromText(const std::string& text,
                                                 const std::string& name = "scene.pbrt") {
  return Scene::Build(ParseSceneString(text, name, "."), SceneBuildOptions{});
}

// Every pixel finite, non-negative and at most `bound`.
inline void ExpectFiniteBounded(const Image& image, float bound) {
  for (size_t i = 0; i < image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const float v = image.pixels[i][c];
      ASSERT_TRUE(std::isfinite(v)) << "pixel " << i << " channel " << c;
      ASSERT_GE(v, 0.f) << "pixel " << i << " channel " << c;
      ASSERT_LE(v, bound) << "pixel " << i << " channel " << c;
    }
}

inline double MeanLuminance(const Image& image) {
  double sum = 0;
  for (const RGB& p : image.pixels) sum += double(p.Luminance());
  return image.pixels.empty() ? 0 : sum / double(image.pixels.size());
}

}  // namespace lightfarm::testing
