// The clamp's expected loss, measured with independent light sets (docs/clamp.md).
//
// A render's own measure of what the clamp removed, Σ (1/d² − 1/max(d², c²)) over its elements
// closer than c, is one draw of an estimator with a finite mean and no variance: near an edge a
// pair closer than d turns up with probability ∝ d³ and then loses ∝ 1/d² (docs/rendering.md,
// "What the compensation leaves"), so from one light set to the next it swings by as much as it
// measures (cornell-box, 20000 lights: 0.08–0.28% over five seeds). The compensation estimates
// the same expectation by path tracing, with finite variance. To tell whether it recovers that
// loss to 0.02% of the image, the expectation has to be known better than one light set knows
// it: this probe averages the loss over many more light sets, each generated exactly as the
// render's (same options, another seed), and evaluates only the pairs the clamp touches
// (receiver and light closer than c), which are few: a thousand light sets cost seconds.
#pragma once

#include <cstddef>
#include <string>

#include <nlohmann/json.hpp>

#include "common/lights/light_generation.h"
#include "common/matrix/lighting_matrix.h"
#include "common/render/render_job.h"
#include "common/receivers/receivers.h"
#include "common/scene/scene.h"

namespace lightfarm {

struct ClampLossProbe {
  int batches = 0;  // independent light sets
  // Expected luminance the geometry clamp removes from the surface rows (row-sum units): the
  // element bound's share of those elements is left out, since the bound also binds beyond c,
  // where the probe does not look (the stats add the render's own measure of it).
  double mean = 0;
  double stderr_ = 0;  // standard error of `mean` over the batches
  // The largest batch's share of the batches' sum: near 1/batches when the loss is spread over
  // many pairs, near 1 when one near-singular pair carries it (the tail the probe is for).
  double largest_share = 0;
  size_t pairs = 0;          // receiver–light pairs closer than c, over all batches
  bool bound_binds = false;  // the element bound can bind (LightingMatrix::bound_binds)
};

// `light_options` and `matrix_options` are the render's; its seed decides the probe's light sets
// (RngStream::kClampProbe), so the probe is deterministic and independent of the render's lights.
ClampLossProbe ProbeClampLoss(const Scene& scene, const ReceiverSet& receivers,
                              const LightGenerationOptions& light_options,
                              const MatrixOptions& matrix_options, int batches);

// `lightfarm render --param clamp_probe=N`: a measurement, not part of the image, so the CLI
// takes it out of the render's parameters (the renderer and the farm never see it) and runs it
// after the render. TakeClampProbe removes the key and returns N (0 without it; OptionError
// outside [0, 100000]).
int TakeClampProbe(RenderSettings* settings);
// Rebuilds the render's plan (deterministic in its seed: the same receivers, options and light
// options) and adds `clamp.probe` to the render's stats, measured against its
// `clamp.unclamped_luminance`: the expected loss beside what the compensation added. Nothing
// for a film method or a render the clamp took nothing from.
void AddClampProbe(const std::string& scene_path, const RenderSettings& settings, int batches,
                   nlohmann::json* stats);

}  // namespace lightfarm
