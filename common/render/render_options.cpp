#include "common/render/render_options.h"

#include <algorithm>

#include "common/receivers/receivers.h"

namespace lightfarm {

namespace {

// The matrix's keys (lighting_matrix.h, MatrixOptions), the clamp aside.
void ReadMatrixOptions(const OptionMap& params, uint64_t seed, MatrixOptions* options) {
  options->segment_samples = int(params.GetInt("segment_samples", 1, 1, 64));
  // The emitters' single scattering in media: on the camera side with this many samples per
  // medium piece, or (0) gathered from their columns by the eye segments.
  options->media_direct_samples = int(params.GetInt("media_direct", 2, 0, 256));
  options->segment_emitter_columns = options->media_direct_samples == 0;
  // Path-traced compensation of the clamp, samples per surface receiver (clamp_compensation.cpp).
  options->compensation_samples = int(params.GetInt("clamp_compensation", 4, 0, 64));
  // ... and in media: eye segments and surface samples that enter a medium (the scene decides
  // the default: the matrix's constructor).
  options->media_compensation =
      int(params.GetOptionalInt("media_compensation", 0, 1, "the scene's (1 when every light is distant or an environment)")
              .value_or(-1));
  // The element bound's scale (MatrixOptions::bsdf_clamp).
  options->bsdf_clamp = float(params.GetDouble("bsdf_clamp", 1.0, 0.0, 1e6));
  options->seed = seed;
  // Caustic photons (caustic_gather.cpp): the scene decides the default (the matrix's constructor).
  options->caustic_photons =
      params.GetOptionalInt("caustic_photons", 0, 1 << 26,
                            "the scene's (" + std::to_string(kDefaultCausticPhotons) + " with caustic paths, else 0)")
          .value_or(-1);
  options->caustic_k = int(params.GetInt("caustic_k", 64, 1, 4096));
  options->caustic_radius = float(params.GetDouble("caustic_radius", 0.02, 1e-6, 1.0));
  options->caustic_volume_radius = float(params.GetDouble("caustic_volume_radius", 0.01, 1e-6, 1.0));
  options->sharp_roughness =
      float(params.GetOptionalDouble("sharp_roughness", 0, 1, "sqrt(20 / lights), between 0.1 and 0.3").value_or(-1));
  options->near_sharp = params.GetInt("near_sharp", 1, 0, 1) != 0;
  options->sharp_samples = int(params.GetInt("sharp_samples", 8, 1, 256));
  options->splits = int(params.GetInt("splits", kDefaultSplits, 0, kMaxSplits));
}

}  // namespace

RenderOptions ReadRenderOptions(const OptionMap& params, uint64_t seed) {
  RenderOptions o;
  o.clamp = params.GetDouble("clamp", 0.01, 0.0, 1.0);
  o.matrix.clamp = float(o.clamp);
  ReadMatrixOptions(params, seed, &o.matrix);
  o.direct_fraction = float(params.GetDouble("direct_fraction", 0.5, 0.0, 1.0));
  // Lights particle paths leave in media: VRLs (Novák 2012; default) or medium VPLs.
  const std::string media_lights = params.GetString("media_lights", "vrl");
  if (media_lights != "vrl" && media_lights != "vpl")
    throw OptionError("--param media_lights=" + media_lights + ": expected vrl or vpl");
  o.media_lights = media_lights == "vrl" ? MediumLights::kVRL : MediumLights::kVPL;
  // Particle paths from independent random points (the default) or quasi-random ones
  // (docs/methods/media-elements.md, "Quasi-random light paths": not yet shown to win).
  const std::string light_paths = params.GetString("light_paths", "random");
  if (light_paths != "random" && light_paths != "halton")
    throw OptionError("--param light_paths=" + light_paths + ": expected random or halton");
  o.quasi_random_paths = light_paths == "halton";
  // VRL columns: pieces of equal in-scattering weight per VRL (light_generation.h).
  o.vrl_pieces = int(params.GetInt("vrl_pieces", 4, 1, 1024));
  const std::optional<long long> camera_paths = params.GetOptionalInt(
      "camera_paths", 0, 4096,
      "the scene's (" + std::to_string(kDefaultCameraPaths) + " with area lights, an environment or sharp lobes, " +
          std::to_string(kDefaultMediaCameraPaths) + " for media_direct, else 0)");
  if (camera_paths) o.camera_paths = int(*camera_paths);
  // Media rows: eye segments of equal in-scattering weight, h + 1 per piece light cannot cross
  // (receivers.h, AppendEyeSegments). Huo 2016 cuts every eye ray at h = 16 points; here h = 0
  // (one row per medium piece, trimmed to the density) renders the media scenes as fast at equal
  // error with fewer rows (docs/methods/media-elements.md).
  o.segments_per_ray = int(params.GetInt("segments_per_ray", 0, 0, 1024));
  o.slicing.rows_per_slice = size_t(params.GetInt("rows_per_slice", 800, 1, 1 << 24));
  o.slicing.seed = seed;
  // Eye-segment slices (Huo 2016, Sec. 4; segment_slicing.h): K = 0.008 × eye rays, clamped to
  // an average of [5/8, 5/4] × segment_rows_per_slice segments per slice (500–1000 for the
  // default 800, the range the paper reports); segment_refine=1 splits segments across slice
  // boundaries (segment_boundary: halves, or svm as the paper) and segment_merge (2.5) rejoins
  // similar pieces (off by default: on volumetric-caustic it changed adaptive-completion's error
  // by less than its noise with near lights, and made it worse without; docs/rendering.md).
  const size_t target = size_t(params.GetInt("segment_rows_per_slice", 800, 1, 1 << 24));
  o.segment_slicing.min_rows_per_slice = std::max<size_t>(1, target * 5 / 8);
  o.segment_slicing.max_rows_per_slice = std::max<size_t>(1, target * 5 / 4);
  o.segment_slicing.refine = params.GetBool("segment_refine", false);
  o.segment_slicing.merge_threshold = float(params.GetDouble("segment_merge", 2.5, 0.0, 4.0));
  const std::string boundary = params.GetString("segment_boundary", "halves");
  if (boundary != "halves" && boundary != "svm")
    throw OptionError("--param segment_boundary=" + boundary + ": expected halves or svm");
  o.segment_slicing.boundary = boundary == "svm" ? SegmentBoundary::kSvm : SegmentBoundary::kHalves;
  o.segment_slicing.seed = seed;
  return o;
}

MethodRenderOptions ReadMethodRenderOptions(const OptionMap& params, const GatherMethod& method) {
  MethodRenderOptions o;
  if (!method.renders_film()) {
    o.coverage = int(params.GetInt("coverage", method.takes_coverage_rows() ? kDefaultCoverage : 1, 1, kMaxCoverage));
    o.coverage_shadows = int(params.GetInt("coverage_shadows", 2, 0, 2));
    o.segment_coverage = int(params.GetInt("segment_coverage", method.takes_coverage_rows() ? kDefaultSegmentCoverage : 1,
                                           1, kMaxCoverage));
  } else {
    o.film_tile = int(params.GetInt("tile", 32, 1, 4096));
    o.film_pass_spp = int(params.GetInt("pass_spp", 64, 1, 1 << 20));
  }
  return o;
}

std::map<std::string, std::string> RenderOptionDefaults() {
  const OptionMap none;
  ReadRenderOptions(none, 0);
  return none.defaults_read();
}

}  // namespace lightfarm
