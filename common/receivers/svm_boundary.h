// The boundary between two neighbouring slices of eye segments (Huo et al. 2016, Sec. 4.2.3): a
// support vector machine with the radial basis function kernel K(x, y) = exp(−‖x − y‖²/(2γ²)),
// γ = 0.5, trained on the start and end points of the segments that border the other slice
// (libsvm, C-SVC). Segment refinement (segment_slicing.h, boundary "svm") splits a segment where
// the decision function changes sign along it.
#pragma once

#include <memory>
#include <vector>

#include "common/util/math.h"

struct svm_model;
struct svm_node;

namespace lightfarm {

class SvmBoundary {
 public:
  // Points of the first slice (label +1) and of the second (label −1). Positions are centred and
  // divided by `scale` first, so γ is relative to it (the slices' extent). Deterministic.
  SvmBoundary(const std::vector<Vec3>& first, const std::vector<Vec3>& second, Vec3 center, float scale,
              double gamma = 0.5);
  ~SvmBoundary();
  SvmBoundary(const SvmBoundary&) = delete;
  SvmBoundary& operator=(const SvmBoundary&) = delete;

  // False when one side had no points (nothing to separate).
  bool valid() const { return model_ != nullptr; }
  // The decision value at x: > 0 on the first slice's side, < 0 on the second's.
  double Decision(Vec3 x) const;
  size_t support_vectors() const;

 private:
  Vec3 center_;
  float inv_scale_ = 1;
  // The training set; the model's support vectors point into nodes_.
  std::vector<svm_node> nodes_;  // 4 per point: x, y, z and libsvm's terminator
  std::vector<svm_node*> points_;
  std::vector<double> labels_;
  svm_model* model_ = nullptr;
  double sign_ = 1;  // libsvm orders labels by first appearance: +1 unless the first point was −1
};

}  // namespace lightfarm
