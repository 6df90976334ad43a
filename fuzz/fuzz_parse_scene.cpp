// libFuzzer target: the pbrt-v4 parser on arbitrary text. Every input must either parse or throw
// SceneError; anything else (a crash, a sanitizer report, another exception) is a bug.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

#include "common/scene/scene_description.h"
#include "common/util/error.h"

namespace {

// Includes resolve against an empty directory of our own, so a fuzzed Include cannot wander
// through the machine's files (the parser already refuses non-regular files such as /dev/zero).
const std::string& EmptyBaseDir() {
  static const std::string dir = [] {
    std::filesystem::path p = std::filesystem::temp_directory_path() / "lightfarm-fuzz-empty";
    std::filesystem::create_directories(p);
    return p.string();
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    lightfarm::SceneDescription desc = lightfarm::ParseSceneString(text, "fuzz.pbrt", EmptyBaseDir());
    (void)desc;
  } catch (const lightfarm::SceneError&) {
    // The documented way to reject input.
  }
  return 0;
}
