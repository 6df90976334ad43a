// Eye-segment slicing (Huo, Wang, Hu, Hua, Bao 2016, Sec. 4): the eye segments become the nodes
// of a graph whose edges link each segment to its nearest spatial neighbours, weighted by the
// segment similarity of Eq. 8 (Eqs. 10–12 and the pixel term); a K-way partition of that graph
// (METIS, minimising the weight of the cut edges) gives the slices of the segment rows; segments
// that cross a slice boundary are then split and similar pieces merged again (Sec. 4.2.3, with the
// paper's RBF-SVM boundary or a simpler split-halves test: see RefineSegmentSlices).
#pragma once

#include <cstdint>
#include <vector>

#include "common/receivers/receivers.h"
#include "common/receivers/slicing.h"
#include "common/scene/scene.h"

namespace lightfarm {

// How refinement finds where a boundary segment crosses from one slice to its neighbour.
enum class SegmentBoundary {
  kHalves,  // split at the middle when the halves are more similar to different slices
  kSvm,     // Huo 2016: an RBF-SVM per pair of neighbouring slices (svm_boundary.h), split
            // where its decision changes sign along the segment
};

struct SegmentSlicingOptions {
  // Huo 2016, Sec. 4.3: K = 0.008 × the number of eye rays (camera samples with a segment) ...
  double slices_per_eye_ray = 0.008;
  // ... clamped so that a slice holds between these many segments on average (the paper reports
  // 500–1000 per slice with its setting; with h = 16 splits per ray the bare 0.008 would give
  // about 2000 here). The target is the documented param `segment_rows_per_slice`.
  size_t min_rows_per_slice = 500;
  size_t max_rows_per_slice = 1000;
  size_t graph_neighbors = 5;      // Sec. 4.2.1: each segment linked to its 5 nearest
  size_t slice_neighbors = 8;      // nearest other slices kept per slice (as point slices)
  float boundary_fraction = 0.125f;  // B = 1/8 of the scene diagonal (Eq. 10)
  float kappa = 0.5f;              // Eq. 11
  float pixel_sigma = 4.f;         // σ of the pixel term (pixels)
  bool refine = true;              // split boundary segments (RefineSegmentSlices); the plan's
                                   // default is off (param segment_refine)
  float merge_threshold = 2.5f;    // Sec. 4.2.3: rejoin a new piece and its neighbour above this
                                   // Eq. 8 similarity (of 4); 0: never
  SegmentBoundary boundary = SegmentBoundary::kHalves;  // param segment_boundary=halves|svm
  uint64_t seed = 0;
};

// What the similarity needs to know about a segment, precomputed once.
struct SegmentFeatures {
  Vec3 x0, x1;         // start and end points
  Vec3 d;              // unit direction of travel
  float g = 0;         // Henyey–Greenstein asymmetry of its medium
  float tau = 1;       // transmittance along the segment (mean of the channels)
  float px = 0, py = 0;  // pixel coordinates of its camera sample
  int16_t medium = -1;
};

struct SegmentSimilarityParams {
  float B = 1;  // Eq. 10: 1/8 of the scene diagonal
  float kappa = 0.5f;
  float pixel_sigma = 4.f;
};

// The four terms of Eq. 8, each in [0, 1] (identical segments: all 1).
struct SegmentSimilarityTerms {
  float spatial = 0, directional = 0, transmittance = 0, pixel = 0;
  float Sum() const { return spatial + directional + transmittance + pixel; }
};

// Huo 2016, Eqs. 8 and 10–12:
//   S = (1/B)·max(0, B − ‖x0i − x0j‖ − ‖x1i − x1j‖)
//   D = κ(2 − d(x0i, x0j) − d(x1i, x1j)), d = the larger relative difference of the two phase
//       functions at the directions where either is largest (clamped to [0, 1]; along a segment
//       direction and medium are constant, so both d are equal here)
//   T = 1 − |τ_i − τ_j|
//   P = exp(−(x̄² + ȳ²) / (2σ)), x̄, ȳ the pixel distances.
// Deviation in P: the paper prints P = 1 − e^{−(x̄²+ȳ²)/2σ}/(2πσ), which would make segments of
// the same pixel the *least* similar and varies by only 1/(2πσ) = 0.04; the Gaussian alone is
// what the text describes (a filter that separates segments of different pixels near the camera).
// κ = 0.5 makes D ∈ [0, 1]. Segments in different media get D = 0.
SegmentSimilarityTerms SegmentSimilarity(const SegmentFeatures& a, const SegmentFeatures& b,
                                         const SegmentSimilarityParams& params);

// Features of every segment of `receivers` (transmittance from its medium: closed form when
// homogeneous, else a ratio-tracking estimate from a hashed generator).
std::vector<SegmentFeatures> ComputeSegmentFeatures(const Scene& scene, const ReceiverSet& receivers,
                                                    uint64_t seed);

// The number of slices for n segments of `eye_rays` rays (Sec. 4.3 with the clamp above).
size_t SegmentSliceCount(size_t segments, size_t eye_rays, const SegmentSlicingOptions& options);

// Partition of the segments: part[s] ∈ [0, K) for each segment s. Graph of the k nearest
// neighbours by endpoint distance (a 3-D kd-tree over start and end points), symmetrised, edge
// weight the similarity; METIS_PartGraphKway with a fixed seed (METIS is serial: the result does
// not depend on the thread count).
std::vector<uint32_t> PartitionSegments(const std::vector<SegmentFeatures>& features, size_t parts,
                                        float scene_diagonal, const SegmentSlicingOptions& options);

// Segment refinement (Sec. 4.2.3): a segment with graph neighbours in another part is split in
// two, each piece joining a part. With SegmentBoundary::kHalves (simplified) it is split at its
// middle when its two halves are more similar (mean Eq. 8 similarity to the segment's neighbours
// in each part) to different parts. With kSvm (the paper's), an RBF-SVM is trained for each pair
// of neighbouring parts on the start and end points of their boundary segments, and a segment is
// split where the decision between its part and the neighbouring part it has most graph edges to
// changes sign along it (bisection); the piece beyond goes to that part. The
// halves replace the segment in `receivers` (same camera sample, contiguous, the second half's
// throughput includes the first half's transmittance), so CameraSample::first_segment/
// segment_count stay valid and the total length per sample is unchanged. Then the paper's merge
// step: a new half and the piece before it on its ray (same medium and part) are joined again
// when their Eq. 8 similarity exceeds options.merge_threshold (2.5), e.g. a half that stays in
// its segment's part next to an unsplit neighbour there. Returns the number of split segments
// (and, in *merged, the number of joins); `part` and `features` follow the new segment order.
size_t RefineSegmentSlices(const Scene& scene, ReceiverSet* receivers,
                           std::vector<SegmentFeatures>* features, std::vector<uint32_t>* part,
                           float scene_diagonal, const SegmentSlicingOptions& options,
                           size_t* merged = nullptr);

// The whole of Sec. 4 for eye segments: features, partition, optional refinement (which changes
// receivers->segments), slices with their nearest neighbouring slices (by midpoint and direction).
// Slice::rows index receivers->segments; Slice::normal is the mean direction. Deterministic.
std::vector<Slice> SliceSegments(const Scene& scene, ReceiverSet* receivers,
                                 const SegmentSlicingOptions& options);

}  // namespace lightfarm
