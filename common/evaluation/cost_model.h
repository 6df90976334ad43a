// Where `lightfarm bench` keeps a scene's results for `--target-error` and `auto` to choose from
// (the choice itself: common/render/method_chooser.h).
#pragma once

#include <filesystem>
#include <string>

namespace lightfarm {

// Where `lightfarm bench` leaves a copy of a scene's results.csv: cache_dir/models/<hash of
// the scene's files>.csv.
std::filesystem::path CostModelPath(const std::string& cache_dir, const std::string& scene);
// And of the truth image that bench measured against (same name, .truth.exr).
std::filesystem::path TruthModelPath(const std::string& cache_dir, const std::string& scene);

}  // namespace lightfarm
