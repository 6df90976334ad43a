// libFuzzer target: the PLY reader on arbitrary bytes (written to a file, since ReadPly reads
// paths). Every input must either load a consistent mesh or throw SceneError.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/scene/ply.h"
#include "common/util/error.h"

namespace {

const std::string& InputPath() {
  // Memory-backed when available: one file write per input is most of the cost.
  static const std::string path =
      ((std::filesystem::is_directory("/dev/shm") ? std::filesystem::path("/dev/shm")
                                                  : std::filesystem::temp_directory_path()) /
       ("lightfarm-fuzz-ply-" + std::to_string(getpid()) + ".ply")).string();
  return path;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  {
    std::ofstream f(InputPath(), std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  try {
    lightfarm::PlyMesh mesh = lightfarm::ReadPly(InputPath());
    // The reader's contract: attribute arrays match the positions, indices are in range and
    // form whole triangles.
    if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size()) std::abort();
    if (!mesh.uvs.empty() && mesh.uvs.size() != mesh.positions.size()) std::abort();
    if (mesh.indices.size() % 3 != 0) std::abort();
    for (int i : mesh.indices)
      if (i < 0 || size_t(i) >= mesh.positions.size()) std::abort();
  } catch (const lightfarm::SceneError&) {
  }
  return 0;
}
