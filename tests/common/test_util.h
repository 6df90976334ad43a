// Helpers shared by the test suites: locating ../shared, temporary directories, small scenes.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

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

}  // namespace lightfarm::testing
