// Progressive references: a job made of passes, each a complete render with its own seed (an
// independent light set and camera samples for brute, an independent sample set for path). The
// passes are accumulated in pass order, in double, so N passes give the same bits however many
// workers ran them; the spread between passes estimates the noise left in their mean.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "common/render/serialize.h"
#include "common/image/image.h"

namespace lightfarm {

// What a job asks of its passes. One pass with no target is an ordinary job.
struct PassPlan {
  uint32_t passes = 1;       // the most passes to run
  double until_noise = 0;    // > 0: stop once both noise estimates are below it
  double time_limit_s = 0;   // > 0: stop after the pass running when this much time has passed

  // Passes a target-only job may run (--until-noise or --time-limit without --passes).
  static constexpr uint32_t kDefaultMaxPasses = 10000;
  // The noise test needs a spread to trust: it starts at this many passes.
  static constexpr uint32_t kMinNoisePasses = 4;

  bool progressive() const { return passes > 1 || until_noise > 0 || time_limit_s > 0; }
  // The passes a request asks for: `requested` when given (> 0), else kDefaultMaxPasses for a
  // job with a target (`targets`' until_noise or time_limit_s), else 1.
  static uint32_t PassesFor(uint32_t requested, const PassPlan& targets) {
    if (requested > 0) return requested;
    return targets.until_noise > 0 || targets.time_limit_s > 0 ? kDefaultMaxPasses : 1;
  }
};

// The seed of pass `pass` of a job seeded `seed`: pass 0 is the job's own seed (one pass equals
// the ordinary job bit for bit), later passes are hashed from (seed, pass).
uint64_t PassSeed(uint64_t seed, uint32_t pass);

// Relative standard errors of the accumulated mean; infinite before two passes.
struct NoiseEstimate {
  double rel_stderr = std::numeric_limits<double>::infinity();      // of the image's mean luminance
  double p90_rel_stderr = std::numeric_limits<double>::infinity();  // 90th percentile over pixels
  double worst() const { return rel_stderr > p90_rel_stderr ? rel_stderr : p90_rel_stderr; }
};

class PassAccumulator {
 public:
  PassAccumulator() = default;

  // Adds the next pass (its image and how long it took). The first pass fixes the size; a pass
  // of another size throws std::invalid_argument.
  void Add(const Image& image, double seconds);

  uint32_t passes() const { return uint32_t(pass_seconds_.size()); }
  const std::vector<double>& pass_seconds() const { return pass_seconds_; }
  // The mean of the passes: Σ image / N per channel, in double, then rounded to float.
  Image Mean() const;
  // rel_stderr: the standard deviation of the passes' mean luminance over √N, over their mean.
  // p90_rel_stderr: per pixel, the standard error of its luminance (Welford's variance over the
  // passes, over √N) over its mean, the 90th percentile over the pixels with a positive mean.
  NoiseEstimate Noise() const;

  Bytes Serialize() const;
  static PassAccumulator Deserialize(ByteView bytes);  // throws SerializeError

 private:
  int width_ = 0, height_ = 0;
  std::vector<double> sum_;        // 3 per pixel: Σ over passes
  std::vector<double> lum_mean_;   // per pixel: Welford's running mean of the luminance
  std::vector<double> lum_m2_;     // per pixel: Welford's Σ (x − mean)²
  std::vector<double> pass_means_; // per pass: its image's mean luminance
  std::vector<double> pass_seconds_;
};

// Passes still needed after `passes` passes with `noise` to reach `target`, at the 1/√N rate the
// estimates fall at; 0 when met, UINT32_MAX when not yet estimated. From a stored estimate, so a
// status call does not recompute the per-pixel percentile.
uint32_t PassesToReach(const NoiseEstimate& noise, uint32_t passes, double target);

// Whether a job that has accumulated `acc` after `elapsed_s` seconds runs another pass.
bool WantsAnotherPass(const PassPlan& plan, const PassAccumulator& acc, double elapsed_s);

}  // namespace lightfarm
