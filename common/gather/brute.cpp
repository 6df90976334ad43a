// `brute`: sums every column for every row, the exact answer for the light set and the
// reference every other method is measured against.
#include <tbb/parallel_for.h>

#include "common/gather/methods.h"

namespace lightfarm {

namespace {

class BruteForceGather final : public GatherMethod {
 public:
  std::string name() const override { return "brute"; }

  TaskOutput RunTask(const GatherContext& ctx, const SubMatrixTask& task,
                     const StageArtifact&) const override {
    const LightingMatrix& matrix = ctx.matrix;
    TaskOutput result;
    result.row_sums.resize(task.rows.size());
    // Rows are independent; each row is summed over all lights in light order, so the result
    // does not depend on how rows are spread over threads.
    constexpr size_t kGrain = 16;
    const size_t nchunks = (task.rows.size() + kGrain - 1) / kGrain;
    std::vector<MatrixCounters> counters(nchunks);
    tbb::parallel_for(size_t(0), nchunks, [&](size_t c) {
      size_t end = std::min(task.rows.size(), (c + 1) * kGrain);
      for (size_t i = c * kGrain; i < end; ++i)
        result.row_sums[i] = matrix.RowSum(task.rows[i], &counters[c]);
    });
    for (const MatrixCounters& c : counters) result.counters.Add(c);
    return result;
  }
};

}  // namespace

std::unique_ptr<GatherMethod> CreateBruteForceGather(const OptionMap&) {
  return std::make_unique<BruteForceGather>();
}

GatherMethodInfo BruteForceMethod() {
  GatherMethodInfo m;
  m.name = "brute";
  m.create = CreateBruteForceGather;
  // Not swept: it is every bench's reference, measured once per light set.
  return m;
}

}  // namespace lightfarm
