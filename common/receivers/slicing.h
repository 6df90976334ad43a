// Row slicing (Ou & Pellacini 2011; Huo et al. 2015, Sec. 4.2): shading points clustered in 6-D
// (position, and normal scaled by the scene size) into slices of about `rows_per_slice` rows,
// each with its nearest neighbouring slices. Slices are the sub-matrices the farm distributes.
#pragma once

#include <cstdint>
#include <vector>

#include "common/receivers/receivers.h"

namespace lightfarm {

struct Slice {
  std::vector<uint32_t> rows;       // indices into ReceiverSet::points, ascending
  std::vector<uint32_t> neighbors;  // ids of the nearest other slices (by 6-D centroid distance)
  Vec3 center;                      // centroid position
  Vec3 normal;                      // mean normal (unit, or zero if they cancel)
};

struct SlicingOptions {
  size_t rows_per_slice = 800;  // Huo 2015 default
  size_t neighbors = 8;         // nearest slices kept per slice
  // Weight of the normal in the 6-D distance, as a fraction of the scene's bounding-box
  // diagonal (position and normal then have comparable scales).
  float normal_weight = 0.25f;
  uint64_t seed = 0;
};

// Deterministic for a given receiver set, scene size and seed, whatever the thread count. Every
// row belongs to exactly one slice; slice ids are their positions in the returned vector.
std::vector<Slice> SliceReceivers(const ReceiverSet& receivers, float scene_diagonal,
                                  const SlicingOptions& options);

}  // namespace lightfarm
