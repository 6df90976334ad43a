// Image error metrics used to compare a method's output with a reference render, and an
// error heatmap for looking at where the error is.
#pragma once

#include <limits>

#include "common/image/image.h"

namespace lightfarm {

struct ErrorMetrics {
  double rel_l2 = 0;  // ‖ref − img‖₂ / ‖ref‖₂ over all pixel channels (Hašan 2007, MRCS)
  double rel_l1 = 0;  // ‖ref − img‖₁ / ‖ref‖₁ over all pixel channels (Huo 2016)
  double rmse = 0;    // sqrt(mean over all pixel channels of (ref − img)²)
  size_t excluded_pixels = 0;  // reference pixels that are NaN/Inf, left out of all three
  size_t excluded_bright = 0;  // reference pixels above exclude_above, left out as well
  // Specks: the share of lit reference pixels (luminance > 0) whose luminance is below 0.3× the
  // smallest, or above 3× the largest, reference luminance in their 3×3 neighbourhood, so the
  // reference's own edges never count (a single-pixel black or bright dot the truth lacks).
  double speck_share = 0;
  size_t dark_specks = 0, bright_specks = 0;
};

// Computed in double. A path-traced reference may hold a stray NaN/Inf pixel (water-caustic's
// does): such pixels are excluded and counted. Throws std::runtime_error if the sizes differ, an
// image is empty, the compared image holds a NaN/Inf (a renderer bug the metrics must not hide),
// or the reference is all zero (relative errors undefined).
// exclude_above leaves out the reference pixels with a channel above it as well (a diagnostic:
// the error without an emitter's own pixels, which a few samples hit or miss).
ErrorMetrics CompareImages(const Image& reference, const Image& image,
                           float exclude_above = std::numeric_limits<float>::infinity());

// Top of the heatmap scale when none is given: an absolute error of 20% of the reference's
// mean luminance (or more) gets the brightest colour.
inline constexpr float kDefaultHeatmapMaxError = 0.2f;

// Per-pixel error e = Luminance(|ref − img|) / mean Luminance(ref). Relative to the *mean*
// rather than to each pixel's own value, so dark pixels don't explode and bright ones don't
// hide. e is mapped linearly from [0, max_error] (clamped) onto HeatmapColor. The result holds
// linear RGB, so WritePNG(path, heatmap) (exposure 1) writes the colour map's sRGB colours.
// Throws as CompareImages does (sizes, non-finite, zero reference) and for max_error <= 0.
Image ErrorHeatmap(const Image& reference, const Image& image,
                   float max_error = kDefaultHeatmapMaxError);

// The heatmap's colour map at t ∈ [0, 1] (clamped), linear RGB: near-black → violet → red →
// orange → pale yellow, with OKLab lightness rising linearly in t (perceptually ordered, still
// readable in greyscale), in the spirit of matplotlib's "inferno".
RGB HeatmapColor(float t);

}  // namespace lightfarm
