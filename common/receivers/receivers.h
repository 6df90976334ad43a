// The rows of the lighting matrix: camera paths traced to their first non-specular vertex.
// Each camera sample belongs to exactly one pixel with a filter weight (filter importance
// sampling, as pbrt-v4), so any subset of samples can be shaded anywhere and assembled later.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "common/image/filter.h"
#include "common/lights/light_generation.h"
#include "common/scene/medium_track.h"
#include "common/scene/scene.h"

namespace lightfarm {

// A receiver on a surface: the camera-side end of every matrix element in its row.
struct ShadingPoint {
  Vec3 p, ng, ns;
  Vec3 wo;          // unit, towards the previous camera-path vertex
  RGB throughput;   // camera-path weight up to here (specular chain), excludes the filter weight
  uint32_t material = 0;
  uint32_t sample = 0;  // index of the camera sample it belongs to
  uint8_t depth = 1;    // scattering events on the camera path, this vertex included
  // Media on the two sides of the surface (indices into Scene::media(), -1 vacuum): medium_out
  // on the side ng points to. Shadow connections towards w start in Dot(w, ng) > 0 ? out : in.
  int16_t medium_out = -1, medium_in = -1;
};

// A receiver along a camera ray inside a medium (Huo 2016, Sec. 3: eye rays through media
// become segments): in-scattered radiance along o + t·d, t ∈ [0, length], reaching the camera
// with `throughput` (camera weight × transmittance from the camera up to o).
struct EyeSegment {
  Vec3 o, d;            // start, unit direction of travel of the camera ray (away from camera)
  float length = 0;
  RGB throughput;
  int16_t medium = -1;  // the medium the segment lies in
  uint8_t depth = 1;    // scattering events on the camera path, the in-scattering included
  uint32_t sample = 0;  // index of the camera sample it belongs to
  // Coverage of a media row (ReceiverOptions::segment_coverage): the row is the mean, over the
  // sample's K coverage rays, of each one's first medium piece (a ray without one adds 0). The
  // `pieces` rays that have one are ReceiverSet::segment_pieces[first_piece, first_piece +
  // pieces), their throughputs scaled by pieces / K, so that one of them drawn uniformly is an
  // unbiased estimate of the mean; a matrix element draws one per sample. The fields above are
  // then those of the first piece (the sample's own ray's, when it has one): the row's place for
  // slicing and distances. 0: the segment is its own row.
  uint32_t first_piece = 0;
  uint16_t pieces = 0;
};

struct CameraSample {
  uint32_t pixel = 0;     // y * width + x
  float weight = 0;       // filter weight f(p)/pdf(p)
  // Emission seen along the camera path (emitters, environment, next-event estimation at sharp
  // vertices); with ReceiverOptions::camera_paths, the pixel's camera-side mean instead.
  RGB emitted;
  // Its shading points: [first_point, first_point + point_count), the rough parts of the
  // vertices its path split at, then the one it ended on (none if it ended without one).
  int32_t first_point = -1;
  uint32_t point_count = 0;
  int32_t first_segment = -1;  // its eye segments: [first_segment, first_segment + segment_count)
  uint32_t segment_count = 0;
};

struct ReceiverStats {
  size_t camera_rays = 0, specular_bounces = 0, escaped = 0, nonfinite_rays = 0;
  size_t transmittance_evals = 0;  // camera-ray segments attenuated through a medium
  size_t camera_paths = 0;         // camera-side paths traced besides the receiver samples
  size_t camera_pilot_paths = 0;   // pilot paths (not in the image)
  size_t camera_active_pixels = 0; // pixels that got camera_paths more paths
  size_t media_direct_samples = 0; // samples of the emitters' single scattering (media_direct_samples)
  size_t split_vertices = 0;       // receiver-path vertices that split (ReceiverOptions::splits)
  size_t near_sharp_vertices = 0;  // receiver-path vertices that took their near-field sharp twin
  size_t coverage_paths = 0;       // camera paths traced for receiver samples beyond one per sample
  size_t segment_coverage = 1;     // film positions per media row (ReceiverOptions::segment_coverage)
};

struct ReceiverSet {
  int width = 0, height = 0, spp = 1;
  std::vector<CameraSample> samples;  // pixel-major: sample s of pixel p is p * spp + s
  std::vector<ShadingPoint> points;   // in sample order
  std::vector<EyeSegment> segments;   // in sample order (empty unless segments_per_ray >= 0)
  std::vector<EyeSegment> segment_pieces;  // the coverage rays' pieces of the segments that have them
  ReceiverStats stats;
};

struct ReceiverOptions {
  int spp = 1;
  uint64_t seed = 0;
  int max_depth = 5;
  // Eye rays through media become segments of equal in-scattering weight, h + 1 where light
  // cannot cross the medium (Huo 2016: h = 16 points per ray), fewer where it can (receivers.cpp,
  // AddEyeSegments). -1: no segments (the camera ray is only attenuated).
  int segments_per_ray = -1;
  // With eye segments: the emitters' single scattering along each camera path's medium pieces is
  // estimated on the camera side with this many samples per piece (t ∝ σ_s·Tr, one emitter sample
  // each), supersampled like the rest of the camera side, and eye-segment rows gather only the
  // lights particle paths left (MatrixOptions::segment_emitter_columns). 0: the emitters' light
  // in media is gathered from their columns by the eye segments.
  int media_direct_samples = 0;
  // Emitter samples per sharp-lobe vertex (docs/rendering.md, "Sharp lobes"), MIS-combined with
  // the lobe's one sample.
  int sharp_samples = 8;
  // Camera-side supersampling (docs/rendering.md, "Camera-side supersampling"): extra camera
  // paths, each with its own film position, that collect only what a camera path collects by
  // itself (emission seen directly or through delta and sharp lobes, next-event estimation at
  // sharp vertices) and end where a receiver would start. A pilot of kCameraPilotPaths paths per
  // pixel, on its own random stream and never part of the image, marks the pixels where that
  // light varies: the pixels within one of a marked pixel share `camera_paths` more paths each,
  // a quarter evenly and the rest in proportion to how much the pilot saw it vary there. The
  // image of every small emitter (kSmallEmitterPixels), seen directly or through delta
  // interactions (found by probing each pixel's delta chains), marks its pixels too, with paths
  // for about kCameraTargetHits hits (at least `camera_paths`). The
  // pixel's camera-side radiance is then the filter-weighted mean over these and its `spp`
  // receiver samples; the gather still runs on the receivers. 0: no pilot, each sample keeps
  // its own (the estimator before this option).
  int camera_paths = 0;
  // Vertices per camera path, at most, that split instead of choosing one way at random
  // (docs/rendering.md, "Split vertices"): at a sharp or delta coat over a rough base the base
  // becomes a receiver and the coat's reflection is followed; at a smooth dielectric both the
  // reflection and the refraction are followed. Later such vertices choose. 0: every one chooses
  // (a sample that follows a coat has no receiver on the base; one reflected by glass sees only
  // the reflection).
  int splits = 0;
  // The near-field rule (docs/rendering.md, "Sharp lobes", *Near field*): a vertex on a material
  // with a near-field sharp twin (Scene::SetSharpAlpha) takes the twin where fewer than 40 lights
  // of a light set like the render's fall in its lobe's footprint. That set is drawn here, on its
  // own seed, with these options (its target_lights 0: the rule is off).
  LightGenerationOptions near_sharp_lights{0};
  // Coverage paths per receiver sample (docs/rendering.md, "Coverage"): the sample traces this
  // many camera paths, each with its own film position, and groups them by the surfaces they end
  // on (material, depth, normal within ~18°, no step off the plane); each group keeps the
  // shading points of one of its paths, chosen in proportion to the filter weights, weighted by
  // the group's share of the sample's weight, and the sample's emission is the mean over all.
  // So a pixel on an edge is shaded where each of its surfaces covers it, and inside a surface
  // it still has one receiver: unbiased (the choice stands in for its group's paths in
  // expectation). 1: one path per sample. Only for filters without negative lobes and without
  // eye segments (media rows keep one path per sample).
  int coverage = 1;
  // Whether the coverage groups also part paths whose points see different emitters (docs/
  // rendering.md, "Coverage": shadow probes), so a pixel across a shadow's edge keeps a receiver
  // on each side as it does across a geometric edge: 0 no, 1 one probe per area emitter (its
  // centroid; 4 in all), 2 one per quarter of it (16 in all), so penumbrae part too. Only the
  // variance depends on it.
  int coverage_shadows = 2;
  // Coverage of media rows (docs/rendering.md, "Coverage of eye segments"): with one segment per
  // medium piece (segments_per_ray 0) and a positive filter, a receiver sample's first medium
  // piece (reached through interfaces only) becomes one row for this many film positions (its
  // own and the coverage lattice's): each element of the row integrates along one of their
  // pieces per sample (EyeSegment::pieces), so the row's sum over many lights averages the
  // pixel's footprint at the cost of one row. 1: one ray per row.
  int segment_coverage = 1;
};
// The most a camera path splits (--param splits).
inline constexpr int kMaxSplits = 16;
// The most coverage paths a receiver sample traces (--param coverage).
inline constexpr int kMaxCoverage = 64;
// Its default.
inline constexpr int kDefaultCoverage = 16;
// The default of --param segment_coverage (docs/methods/media-elements.md, "Coverage of eye
// segments").
inline constexpr int kDefaultSegmentCoverage = 16;
// The coverage pieces' tracks hold about this many knots at most (16 bytes each): K is lowered
// for images whose media rows would need more (receivers.cpp).
inline constexpr size_t kSegmentCoverageKnots = size_t(1) << 24;
// The default of --param camera_paths for a scene whose camera paths can collect light by
// themselves (render_job.cpp, CameraPathsFor).
inline constexpr int kDefaultCameraPaths = 256;
// ... and for a scene whose only camera-side light is the emitters' single scattering in media.
inline constexpr int kDefaultMediaCameraPaths = 64;
// Single-scattering samples the camera-side paths of an active pixel share (at least
// media_direct per path): docs/methods/media-elements.md, "Quasi-random light paths".
inline constexpr int kCameraMediaPixelSamples = 512;
inline constexpr int kCameraPilotPaths = 4;
// The active pixels share camera_paths paths each (receivers.cpp, ShareActivePaths): this share
// of them evenly, the rest in proportion to the pilot's spread over each pixel's neighbourhood.
inline constexpr double kEvenActiveShare = 0.25;
// An emissive shape whose image fits in this many pixels across activates its pixels without the
// pilot (receivers.cpp).
inline constexpr float kSmallEmitterPixels = 4.f;
// ... and whose image through a thin lens, blurred, fits in this many.
inline constexpr float kSmallEmitterBlurPixels = 64.f;
// A pixel marked by a small emitter's image (seen directly or through delta interactions) gets
// enough camera paths for about this many of them to hit the light, by the image's estimated
// share of the pixel and the Fresnel odds of the branch it lies on, and at most kMaxCameraPaths
// (or camera_paths, if more); the highest estimated hit rates first, while the marked pixels'
// paths stay within kMarkedPathsPerPixel times the image's pixels (or kMinMarkedPaths).
inline constexpr double kCameraTargetHits = 64;
inline constexpr int kMaxCameraPaths = 65536;
inline constexpr double kMarkedPathsPerPixel = 4;
inline constexpr double kMinMarkedPaths = 1 << 20;

// The scene's pixel filter (PixelFilter directive, or the override the scene was built with).
std::unique_ptr<Filter> MakePixelFilter(const RenderHints& hints);

// Cuts the camera ray piece o + t·d, t ∈ [0, tmax], in `medium` into eye segments of equal
// in-scattering weight (MediumTrack) and appends them: a piece light cannot cross into h + 1
// (Huo 2016, Sec. 4.1: h = 16 points along every eye ray), one it crosses with probability Tr
// into max(1, ⌈(h + 1)(1 − Tr)⌉), so rows are short where the medium is dense and slices can be
// compact there. Each is trimmed to where the density may be non-zero; empty space makes none.
// beta is the camera weight up to o; a segment's throughput is beta × the exact transmittance
// to its start. Returns the transmittance of the whole piece. Deterministic (no random choice).
RGB AppendEyeSegments(const Medium& med, int medium, const Ray& ray, float tmax, RGB beta, int h,
                      uint8_t depth, std::vector<EyeSegment>* out);
// The same cuts of a piece already tabulated (track along ray from ray.o).
void AppendEyeSegments(const MediumTrack& track, int medium, const Ray& ray, RGB beta, int h, uint8_t depth,
                       std::vector<EyeSegment>* out);

// Deterministic: every pixel draws from its own hashed generator and scrambled Sobol points.
ReceiverSet GenerateReceivers(const Scene& scene, const FilterSampler& filter,
                              const ReceiverOptions& opt);

}  // namespace lightfarm
