// Helpers shared by the test suites: locating ../shared, temporary directories, small scenes.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "common/render/render_job.h"

namespace lightfarm::testing {

// The shared data directory: $LIGHTFARM_SHARED, else <source>/../shared. A missing directory is
// a failure (tests never skip themselves to pass).
inline std::string SharedDir() {
  if (const char* env = std::getenv("LIGHTFARM_SHARED")) return env;
  return std::string(LIGHTFARM_SOURCE_DIR) + "/../shared";
}

inline std::string SharedScene(const std::string& name) {
  std::string path = SharedDir() + "/scenes/" + name + "/scene.pbrt";
  if (!std::filesystem::exists(path))
    ADD_FAILURE() << "shared scene missing: " << path
                  << " (set LIGHTFARM_SHARED to the shared/ directory)";
  return path;
}

inline std::string SourcePath(const std::string& rel) {
  return std::string(LIGHTFARM_SOURCE_DIR) + "/" + rel;
}

// The project's example scene (scenes/cornell-box), the farm and CLI tests' usual job.
inline std::string ExampleCornellBox() { return SourcePath("scenes/cornell-box/scene.pbrt"); }

// A unit quad in the z = 0 plane, as a scene line.
inline const std::string kQuad =
    "Shape \"trianglemesh\" \"point3 P\" [-1 -1 0 1 -1 0 1 1 0 -1 1 0]"
    " \"integer indices\" [0 1 2 0 2 3]\n";

// The smallest complete scene: 8×8 pixels, a point light over the quad.
inline const std::string kTinyScene =
    "Film \"rgb\" \"integer xresolution\" [8] \"integer yresolution\" [8]\n"
    "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\nWorldBegin\n"
    "LightSource \"point\" \"rgb I\" [5 5 5] \"point3 from\" [0 0 3]\n" + kQuad;

// A fresh directory under the system temp dir, removed when the object dies.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() /
            ("lightfarm-test-" + std::to_string(rd()) + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string Path(const std::string& name) const { return (path_ / name).string(); }
  std::string Write(const std::string& name, const std::string& text) const {
    std::string p = Path(name);
    std::filesystem::create_directories(std::filesystem::path(p).parent_path());
    std::ofstream(p) << text;
    return p;
  }

 private:
  std::filesystem::path path_;
};

// Elements of the lighting matrix a render evaluated (stats "matrix.elements_evaluated").
inline uint64_t Elements(const RenderOutput& out) {
  return out.stats["matrix"]["elements_evaluated"].get<uint64_t>();
}

// Every pixel channel of img within rel (relative) of ref.
inline void ExpectImagesNear(const Image& ref, const Image& img, float rel) {
  ASSERT_TRUE(ref.SameSize(img));
  for (size_t i = 0; i < ref.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c)
      ASSERT_NEAR(img.pixels[i][c], ref.pixels[i][c], rel * std::abs(ref.pixels[i][c]) + 1e-7f)
          << "pixel " << i << " channel " << c;
}

// Bitwise equality of two images (NaN-safe).
inline ::testing::AssertionResult SameBits(const Image& a, const Image& b) {
  if (!a.SameSize(b))
    return ::testing::AssertionFailure() << "sizes differ: " << a.width << "x" << a.height << " vs " << b.width
                                         << "x" << b.height;
  if (a.pixels.empty()) return ::testing::AssertionFailure() << "empty image";
  if (std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(RGB)) != 0) {
    for (size_t i = 0; i < a.pixels.size(); ++i)
      if (std::memcmp(&a.pixels[i], &b.pixels[i], sizeof(RGB)) != 0)
        return ::testing::AssertionFailure() << "pixel " << i << " differs: " << a.pixels[i].r << " vs "
                                             << b.pixels[i].r;
  }
  return ::testing::AssertionSuccess();
}

}  // namespace lightfarm::testing
