// The renderer-wide --param keys: what a render reads whatever its method (the clamp, the
// matrix's elements, slicing, media rows and columns, camera-side paths), typed and read in this
// one place, each with its one default. A method's own keys are read in its file (gather.h);
// the coverage paths and the film methods' tiling depend on the method and are read once it is
// known (ReadMethodRenderOptions). The plan and every worker read through these functions, and
// `lightfarm methods` prints every default from them (RenderOptionDefaults).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "common/gather/gather.h"
#include "common/lights/light_generation.h"
#include "common/matrix/lighting_matrix.h"
#include "common/receivers/segment_slicing.h"
#include "common/receivers/slicing.h"
#include "common/util/options.h"

namespace lightfarm {

struct RenderOptions {
  // The geometry-term clamp, a fraction of the scene's bounding-sphere radius (also in matrix.clamp).
  double clamp = 0;
  MatrixOptions matrix;
  // Lights: the share of --lights spent on the emitters themselves, what particle paths leave in
  // media, and the pieces each VRL is cut into (light_generation.h).
  float direct_fraction = 0;
  MediumLights media_lights = MediumLights::kVRL;
  int vrl_pieces = 1;
  bool quasi_random_paths = false;  // light_paths=halton (LightGenerationOptions::quasi_random_paths)
  // Receivers: camera-side paths per pixel (ReceiverOptions::camera_paths; absent: what the
  // scene calls for) and the split points per eye ray in a medium (ReceiverOptions::segments_per_ray).
  std::optional<int> camera_paths;
  int segments_per_ray = 0;
  // Row tiles: receiver slices and eye-segment slices.
  SlicingOptions slicing;
  SegmentSlicingOptions segment_slicing;
};

// Reads every renderer-wide key of `params` (marking it used); throws OptionError on a value out
// of range or of the wrong type.
RenderOptions ReadRenderOptions(const OptionMap& params, uint64_t seed);

// The keys whose meaning depends on the method: a matrix method's coverage paths per receiver
// sample and film positions per media row (ReceiverOptions::coverage and segment_coverage; one
// for a method whose rows should not be coverage points, GatherMethod::takes_coverage_rows), a film method's tiles and sample passes (FilmTasks). Read
// only for the methods they apply to, so the others reject them as unknown.
struct MethodRenderOptions {
  int coverage = 1;
  int coverage_shadows = 2;  // ReceiverOptions::coverage_shadows
  int segment_coverage = 1;  // ReceiverOptions::segment_coverage
  int film_tile = 0;
  int film_pass_spp = 0;
};
MethodRenderOptions ReadMethodRenderOptions(const OptionMap& params, const GatherMethod& method);

// Every renderer-wide key with its default as text ("the scene's" where the scene decides).
std::map<std::string, std::string> RenderOptionDefaults();

}  // namespace lightfarm
