// The truth a bench measures every run against, besides same-lights brute force: a converged
// image of the scene, either a file (the scene's reference.exr, area-averaged to the bench's
// resolution) or rendered here by the `path` method in independent passes until the estimated
// noise of their mean is below a stated level. Its own noise is part of every number measured
// against it, so it is estimated and reported with it.
#pragma once

#include <cstdint>
#include <string>

#include "common/render/render_job.h"
#include "common/image/image.h"

namespace lightfarm {

struct TruthRequest {
  std::string scene;
  // "path": render with the path method; otherwise an image file. Empty: the scene's
  // reference.exr when one sits beside it, else "path".
  std::string source;
  int width = 0, height = 0;  // the bench's resolution (a file is area-averaged to it)
  std::string filter;         // the bench's filter override (path truths are rendered with it)
  uint64_t seed = 0;
  double noise = 0.01;        // path: stop when the estimated rel_l1 noise is at most this
  int pass_spp = 64;          // path: samples per pixel of each pass
  double max_seconds = 3600;  // path: stop after the pass that ends past this, noise or not
  std::string cache_dir;      // path truths are cached here (empty: no cache)
};

struct Truth {
  Image image;
  std::string label;     // what it is, for the report ("path-traced, 16 passes × 64 spp" / a file)
  std::string source;    // "path" or the file's path
  bool path_traced = false;
  int passes = 0, spp = 0;  // path: passes and total samples per pixel
  double seconds = 0;       // path: render time (of the run that computed it)
  // The truth's own expected rel_l1 and rel_l2 from its noise (path: from the per-pixel variance
  // over passes; a file: unknown, NaN).
  double noise_rel_l1 = 0, noise_rel_l2 = 0;
  bool from_cache = false;
};

// The source an empty request resolves to: the scene's reference.exr if present, else "path".
std::string DefaultTruthSource(const std::string& scene);

// Loads (file), loads from the cache, or renders (path) the truth. Throws std::runtime_error
// for an unreadable file or OptionError for a bad request.
Truth GetTruth(const TruthRequest& request);

struct TruthMetrics {
  double rel_l1 = 0, rel_l2 = 0;
  // Share of pixels whose luminance is more than 3× above or below the truth's 3×3 local mean
  // (beyond 1% of the truth's mean luminance): specks and fireflies a mean error hides.
  double fireflies = 0;
};

TruthMetrics CompareWithTruth(const Truth& truth, const Image& image);

// The fireflies figure alone (exposed for tests).
double FireflyShare(const Image& truth, const Image& image);

}  // namespace lightfarm
