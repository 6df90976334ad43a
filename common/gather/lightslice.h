// The per-slice step of LightSlice (Ou & Pellacini 2011), separate from the stages in
// lightslice.cpp (which defines it) so that tests can check it on small matrices of their own.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <span>

#include "common/gather/mrcs_clustering.h"

namespace lightfarm {

struct LightSliceLocalOptions {
  size_t clusters = 300;   // C_local: representative columns of the slice
  // Share of C_local given to the lights dark on every local row (at least 1 if any); < 0: their
  // share of all lights, as mrcs's zero_share.
  double dark_share = -1;
};

struct LightSliceLocalClustering {
  // Lit clusters first (pmf ∝ local norm), then the dark ones (pmf ∝ power luminance);
  // `objective` is the lit clusters' MRCS objective on the local columns.
  MrcsClustering clustering;
  double global_objective = 0;  // the same lit lights grouped only by their global clusters
  size_t lit_global_groups = 0;  // non-empty (global cluster ∩ lit lights): the start of the split
};

// Refines the global clustering for one slice. `local` is d × n: the reduced (RGB → 2-norm)
// values of every light on the slice's and its neighbours' sampled rows. Lights with a non-zero
// local column start in their global cluster (`global_of`, one id per light) and the most costly
// clusters on the local columns are split (mrcs_clustering.h, top-down splitting) until the lit
// part has its share of C_local; lights dark on every local row are cut into runs of equal power
// in global-cluster order (lights that behave alike elsewhere stay together) and sampled ∝ power,
// so none is dropped. C_local >= n gives every light its own cluster (pmf 1: the exact sum).
// Deterministic in `seed`.
LightSliceLocalClustering LightSliceRefine(const Eigen::MatrixXf& local,
                                           std::span<const uint32_t> global_of,
                                           std::span<const float> power,
                                           const LightSliceLocalOptions& options, uint64_t seed);

}  // namespace lightfarm
