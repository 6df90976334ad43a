#include "coordinator/job_images.h"

#include <algorithm>
#include <filesystem>

#include "common/render/stage_engine.h"
#include "common/image/image_io.h"
#include "common/util/file.h"

namespace lightfarm {

Bytes WriteResultExr(const Image& image, const std::string& path) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  WriteEXR(path, image);
  const std::string bytes = ReadFile(path);
  return Bytes(bytes.begin(), bytes.end());
}

JobPreview MakePreview(Image image, uint64_t version, const std::string& path) {
  const double shrink = std::min(1.0, double(JobPreview::kMaxSide) / std::max(image.width, image.height));
  JobPreview preview;
  preview.width = std::max(1, int(image.width * shrink + 0.5));
  preview.height = std::max(1, int(image.height * shrink + 0.5));
  preview.tiles = version;
  if (preview.width != image.width || preview.height != image.height)
    image = ResizeImage(image, preview.width, preview.height);
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  WritePNG(path, image);
  preview.png = ReadFile(path);
  return preview;
}

JobPreview MakePreview(const Plan& plan, const std::vector<std::pair<SubMatrixTask, TaskOutput>>& tiles,
                       const std::string& path) {
  uint64_t nan_samples = 0;
  return MakePreview(AssembleImage(plan, PartialOutcome(plan, tiles), &nan_samples), tiles.size(), path);
}

}  // namespace lightfarm
