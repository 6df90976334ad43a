// The images the coordinator makes of a job: the result EXR that FetchResult streams, and the
// preview PNG of the finished tiles that WatchJob sends while the final stage runs. Both go
// through files in the job's directory (OpenImageIO writes files) and come back as bytes.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "common/render/render_job.h"
#include "common/render/serialize.h"

namespace lightfarm {

struct JobPreview {
  std::string png;       // tone-mapped sRGB, at most kMaxSide pixels a side
  int width = 0, height = 0;
  uint64_t tiles = 0;    // final-stage tasks it shows (progressive jobs: finished passes << 32)
  static constexpr int kMaxSide = 256;
};

// A job's result image written as an EXR at `path`; returns the file's bytes.
Bytes WriteResultExr(const Image& image, const std::string& path);

// The finished final-stage tiles (task order; the other pixels black), shrunk to at most
// JobPreview::kMaxSide pixels a side, written as a PNG at `path`.
// A preview of `image` (shrunk, PNG at `path`); `version` orders previews for the watchers
// (JobPreview::tiles: the tiles shown, or a progressive job's passes << 32).
JobPreview MakePreview(Image image, uint64_t version, const std::string& path);
JobPreview MakePreview(const Plan& plan, const std::vector<std::pair<SubMatrixTask, TaskOutput>>& tiles,
                       const std::string& path);

}  // namespace lightfarm
