#include "common/evaluation/cost_model.h"

#include "common/evaluation/reference.h"

namespace lightfarm {

std::filesystem::path CostModelPath(const std::string& cache_dir, const std::string& scene) {
  return std::filesystem::path(cache_dir) / "models" / (SceneFilesHash(scene) + ".csv");
}

std::filesystem::path TruthModelPath(const std::string& cache_dir, const std::string& scene) {
  return std::filesystem::path(cache_dir) / "models" / (SceneFilesHash(scene) + ".truth.exr");
}

}  // namespace lightfarm
