#include "common/receivers/svm_boundary.h"

#include <libsvm/svm.h>

#include <mutex>

namespace lightfarm {

namespace {

void Quiet(const char*) {}

}  // namespace

SvmBoundary::SvmBoundary(const std::vector<Vec3>& first, const std::vector<Vec3>& second, Vec3 center,
                         float scale, double gamma)
    : center_(center), inv_scale_(scale > 0 ? 1.f / scale : 1.f) {
  if (first.empty() || second.empty()) return;
  static std::once_flag quiet;
  std::call_once(quiet, [] { svm_set_print_string_function(Quiet); });
  const size_t n = first.size() + second.size();
  nodes_.resize(4 * n);
  points_.resize(n);
  labels_.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const bool is_first = i < first.size();
    const Vec3 p = ((is_first ? first[i] : second[i - first.size()]) - center_) * inv_scale_;
    svm_node* x = &nodes_[4 * i];
    for (int a = 0; a < 3; ++a) x[a] = svm_node{a + 1, double(p[a])};
    x[3] = svm_node{-1, 0.0};
    points_[i] = x;
    labels_[i] = is_first ? 1.0 : -1.0;
  }
  svm_problem problem{};
  problem.l = int(n);
  problem.y = labels_.data();
  problem.x = points_.data();
  svm_parameter param{};
  param.svm_type = C_SVC;
  param.kernel_type = RBF;
  param.gamma = 1.0 / (2.0 * gamma * gamma);  // libsvm's RBF is exp(−gamma·‖x − y‖²)
  param.C = 1;
  param.cache_size = 16;  // MiB
  param.eps = 1e-3;
  param.shrinking = 1;
  param.probability = 0;
  if (svm_check_parameter(&problem, &param) != nullptr) return;
  model_ = svm_train(&problem, &param);
  // The decision value is positive for the label of the first training point.
  sign_ = labels_[0] > 0 ? 1.0 : -1.0;
}

SvmBoundary::~SvmBoundary() {
  if (model_) svm_free_and_destroy_model(&model_);
}

double SvmBoundary::Decision(Vec3 x) const {
  if (!model_) return 0;
  const Vec3 p = (x - center_) * inv_scale_;
  const svm_node node[4] = {{1, double(p.x)}, {2, double(p.y)}, {3, double(p.z)}, {-1, 0.0}};
  double value = 0;
  svm_predict_values(model_, node, &value);
  return sign_ * value;
}

size_t SvmBoundary::support_vectors() const { return model_ ? size_t(model_->l) : 0; }

}  // namespace lightfarm
