// The rows of the lighting matrix: camera paths traced to their first non-specular vertex.
// Each camera sample belongs to exactly one pixel with a filter weight (filter importance
// sampling, as pbrt-v4), so any subset of samples can be shaded anywhere and assembled later.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "common/image/filter.h"
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
};

struct CameraSample {
  uint32_t pixel = 0;     // y * width + x
  float weight = 0;       // filter weight f(p)/pdf(p)
  // Emission seen along the camera path (emitters, environment, next-event estimation at sharp
  // vertices); with ReceiverOptions::camera_paths, the pixel's camera-side mean instead.
  RGB emitted;
  int32_t point = -1;     // index of its shading point, -1 if the path ended without one
  int32_t first_segment = -1;  // its eye segments: [first_segment, first_segment + segment_count)
  uint32_t segment_count = 0;
};

struct ReceiverStats {
  size_t camera_rays = 0, specular_bounces = 0, escaped = 0, nonfinite_rays = 0;
  size_t transmittance_evals = 0;  // camera-ray segments attenuated through a medium
  size_t camera_paths = 0;         // camera-side paths traced besides the receiver samples
  size_t camera_pilot_paths = 0;   // pilot paths (not in the image)
  size_t camera_active_pixels = 0; // pixels that got camera_paths more paths
};

struct ReceiverSet {
  int width = 0, height = 0, spp = 1;
  std::vector<CameraSample> samples;  // pixel-major: sample s of pixel p is p * spp + s
  std::vector<ShadingPoint> points;   // in sample order
  std::vector<EyeSegment> segments;   // in sample order (empty unless segments_per_ray >= 0)
  ReceiverStats stats;
};

struct ReceiverOptions {
  int spp = 1;
  uint64_t seed = 0;
  int max_depth = 5;
  // Eye rays through media become h + 1 segments split at h points placed by delta tracking
  // (Huo 2016: h = 16). -1: no segments (the camera ray is only attenuated).
  int segments_per_ray = -1;
  // Emitter samples per sharp-lobe vertex (docs/rendering.md, "Sharp lobes"), MIS-combined with
  // the lobe's one sample.
  int sharp_samples = 8;
  // Camera-side supersampling (docs/rendering.md, "Camera-side supersampling"): extra camera
  // paths, each with its own film position, that collect only what a camera path collects by
  // itself (emission seen directly or through delta and sharp lobes, next-event estimation at
  // sharp vertices) and end where a receiver would start. A pilot of kCameraPilotPaths paths per
  // pixel, on its own random stream and never part of the image, marks the pixels where that
  // light varies: every pixel within one of a marked pixel gets `camera_paths` more paths. The
  // image of every small emitter (kSmallEmitterPixels), seen directly or through delta
  // interactions (found by probing each pixel's delta chains), marks its pixels too, with paths
  // for about kCameraTargetHits hits (at least `camera_paths`). The
  // pixel's camera-side radiance is then the filter-weighted mean over these and its `spp`
  // receiver samples; the gather still runs on the receivers. 0: no pilot, each sample keeps
  // its own (the estimator before this option).
  int camera_paths = 0;
};
// The default of --param camera_paths for a scene whose camera paths can collect light by
// themselves (render_job.cpp, CameraPathsFor).
inline constexpr int kDefaultCameraPaths = 256;
inline constexpr int kCameraPilotPaths = 4;
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

// Deterministic: every pixel draws from its own hashed generator and scrambled Sobol points.
ReceiverSet GenerateReceivers(const Scene& scene, const FilterSampler& filter,
                              const ReceiverOptions& opt);

}  // namespace lightfarm
