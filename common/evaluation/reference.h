// The brute-force reference a bench measures every method against: the same scene, lights,
// receivers and seed, summed over every column. Cached on disk by a hash of the scene files and
// everything that decides the light set and the receivers, so a second bench reuses it and any
// change (a scene file, --lights, --resolution, --spp, --seed, --param clamp=...) recomputes it.
//
// Full brute force casts lights × receivers shadow rays, unaffordable at 10^5-10^6 lights and
// 256² on a small machine. With `pixels` > 0 the reference is exact on a fixed, seeded random
// subset of pixels only: brute force evaluates RowSum for the receivers of those pixels' camera
// samples (same rows, same lights, same film weights) and errors are measured on that subset.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/render/render_job.h"
#include "common/image/image.h"
#include "common/image/metrics.h"

namespace lightfarm {

struct ReferenceRequest {
  std::string scene;
  RenderSettings settings;  // method is ignored (brute); the rest decides the matrix
  size_t pixels = 0;        // 0: the full image; else a seeded random subset of this many pixels
  std::string cache_dir;    // empty: no cache
};

struct BenchReference {
  std::string key;               // cache key (hex)
  Image image;                   // full size; outside `pixels` it is zero for a subset reference
  std::vector<uint32_t> pixels;  // the subset's pixel indices (ascending); empty: full image
  double brute_seconds = 0;      // time of full brute force (extrapolated for a subset)
  double brute_shadow_rays = 0;  // shadow rays of full brute force (extrapolated for a subset)
  double brute_elements = 0;     // matrix elements of full brute force (rows × lights)
  bool extrapolated = false;     // brute_* scaled from the subset's rows to all rows
  size_t lights = 0;             // actual light count
  bool from_cache = false;
};

// Hex digest of the scene's files (the scene file and every file it names, transitively;
// contents for files up to 64 MiB, size and mtime above) and of the settings that decide the
// matrix and the film. The same request gives the same key in any process.
std::string ReferenceKey(const ReferenceRequest& request);

// Hex digest of the scene's files alone (the key of a scene's bench cost model).
std::string SceneFilesHash(const std::string& scene);

// Loads the cached reference or computes (and caches) it.
BenchReference GetReference(const ReferenceRequest& request);

// Loads a cached reference without computing; false when there is none.
bool LoadCachedReference(const ReferenceRequest& request, BenchReference* out);

// How many references this process computed (not loaded): the tests' proof of cache reuse.
uint64_t ReferenceComputations();

// The seeded pixel subset: `count` distinct pixel indices of a width × height image, ascending.
std::vector<uint32_t> ReferencePixelSubset(int width, int height, size_t count, uint64_t seed);

// rel_l2 / rel_l1 of `image` against the reference, over its pixels (all, or the subset).
ErrorMetrics CompareWithReference(const BenchReference& reference, const Image& image);

}  // namespace lightfarm
