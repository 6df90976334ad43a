#include "common/evaluation/truth.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "common/evaluation/reference.h"
#include "common/image/image_io.h"
#include "common/image/metrics.h"
#include "common/util/error.h"
#include "common/util/file.h"
#include "common/util/rng.h"

namespace lightfarm {

namespace fs = std::filesystem;

namespace {

constexpr int kTruthFormat = 2;  // bump when a cached truth's meaning changes (2: own seed)
// The truth's samples come from their own seed: a `path` run of the bench with the job seed must
// not share samples with the image it is measured against.
constexpr uint64_t kTruthSeedStream = 0x7E57;
constexpr int kMinPasses = 4;    // fewer passes give no usable variance

std::string TruthKey(const TruthRequest& r) {
  std::string text = "truth" + std::to_string(kTruthFormat) + "|" + SceneFilesHash(r.scene) + "|" +
                     std::to_string(r.width) + "x" + std::to_string(r.height) + "|" + r.filter + "|" +
                     std::to_string(r.seed) + "|" + std::to_string(r.noise) + "|" + std::to_string(r.pass_spp) +
                     "|" + std::to_string(r.max_seconds);
  // FNV-1a of the description: short and stable.
  uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : text) h = (h ^ c) * 0x100000001b3ULL;
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

// Per-pixel mean and variance over passes (Welford, double) and what they say about the noise of
// the mean: E|x̄ − μ| = σ/√n · √(2/π) per channel for a normal mean.
class PassAccumulator {
 public:
  void Add(const Image& img) {
    if (n_ == 0) {
      width_ = img.width;
      height_ = img.height;
      mean_.assign(img.pixels.size() * 3, 0.0);
      m2_.assign(img.pixels.size() * 3, 0.0);
    }
    ++n_;
    for (size_t i = 0; i < img.pixels.size(); ++i)
      for (int c = 0; c < 3; ++c) {
        const double x = double(img.pixels[i][c]);
        double& mean = mean_[3 * i + size_t(c)];
        const double d = x - mean;
        mean += d / double(n_);
        m2_[3 * i + size_t(c)] += d * (x - mean);
      }
  }
  int passes() const { return n_; }
  double NoiseRelL1() const {
    double dev = 0, sum = 0;
    for (size_t k = 0; k < mean_.size(); ++k) {
      dev += std::sqrt(m2_[k] / double(n_ - 1) / double(n_));
      sum += std::abs(mean_[k]);
    }
    return sum > 0 ? std::sqrt(2 / M_PI) * dev / sum : 0.0;
  }
  double NoiseRelL2() const {
    double var = 0, sq = 0;
    for (size_t k = 0; k < mean_.size(); ++k) {
      var += m2_[k] / double(n_ - 1) / double(n_);
      sq += mean_[k] * mean_[k];
    }
    return sq > 0 ? std::sqrt(var / sq) : 0.0;
  }
  Image Mean() const {
    Image img(width_, height_);
    for (size_t i = 0; i < img.pixels.size(); ++i)
      img.pixels[i] = RGB(float(mean_[3 * i]), float(mean_[3 * i + 1]), float(mean_[3 * i + 2]));
    return img;
  }

 private:
  int n_ = 0, width_ = 0, height_ = 0;
  std::vector<double> mean_, m2_;
};

Truth RenderPathTruth(const TruthRequest& r) {
  const auto start = std::chrono::steady_clock::now();
  RenderSettings s;
  s.method = "path";
  s.width = r.width;
  s.height = r.height;
  s.filter = r.filter;
  s.seed = HashSeed({r.seed, kTruthSeedStream});
  s.spp = r.pass_spp;
  Plan plan = BuildPlan(r.scene, s, nullptr);
  PassAccumulator acc;
  Truth t;
  for (int pass = 0;; ++pass) {
    // Pass k takes samples [k·S, (k+1)·S) of every pixel: independent of the other passes (its
    // own generators), and together the passes are one render of passes × S samples.
    for (SubMatrixTask& task : plan.tasks) {
      task.sample_begin = uint32_t(pass) * uint32_t(r.pass_spp);
      task.sample_end = task.sample_begin + uint32_t(r.pass_spp);
    }
    const GatherOutcome outcome = RunStagesLocally(plan, nullptr, nullptr);
    acc.Add(AssembleImage(plan, outcome, nullptr));
    t.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (acc.passes() < kMinPasses) continue;
    t.noise_rel_l1 = acc.NoiseRelL1();
    t.noise_rel_l2 = acc.NoiseRelL2();
    spdlog::info("truth: {} passes × {} spp, estimated noise rel_l1 {:.4f} (target {}), {:.1f} s", acc.passes(),
                 r.pass_spp, t.noise_rel_l1, r.noise, t.seconds);
    if (t.noise_rel_l1 <= r.noise || t.seconds >= r.max_seconds || acc.passes() >= (1 << 20) / r.pass_spp) break;
  }
  if (t.noise_rel_l1 > r.noise)
    spdlog::warn("truth: stopped at {:.0f} s with noise rel_l1 {:.4f} above the target {}", t.seconds,
                 t.noise_rel_l1, r.noise);
  t.image = acc.Mean();
  t.passes = acc.passes();
  t.spp = acc.passes() * r.pass_spp;
  return t;
}

std::string PathLabel(const Truth& t) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "path-traced here (`path`, MIS): %d passes × %d spp = %d spp, %.0f s; "
                "its own noise: rel_l1 %.4f, rel_l2 %.4f", t.passes, t.spp / std::max(1, t.passes), t.spp,
                t.seconds, t.noise_rel_l1, t.noise_rel_l2);
  return buf;
}

}  // namespace

std::string DefaultTruthSource(const std::string& scene) {
  const fs::path ref = fs::path(scene).parent_path() / "reference.exr";
  return fs::exists(ref) ? ref.string() : "path";
}

Truth GetTruth(const TruthRequest& request) {
  TruthRequest r = request;
  if (r.source.empty()) r.source = DefaultTruthSource(r.scene);
  if (r.width <= 0 || r.height <= 0) throw OptionError("truth: the bench's resolution is needed");
  if (r.source != "path") {
    Truth t;
    t.source = r.source;
    const Image file = ReadImage(r.source);
    t.image = file.width == r.width && file.height == r.height ? file : ResizeImage(file, r.width, r.height);
    t.noise_rel_l1 = t.noise_rel_l2 = std::nan("");
    t.label = "the file " + r.source + " (" + std::to_string(file.width) + "x" + std::to_string(file.height) +
              (file.width == r.width && file.height == r.height ? "" : ", area-averaged to " + std::to_string(r.width) +
                                                                         "x" + std::to_string(r.height)) +
              "); its own noise is not known";
    return t;
  }
  if (!(r.noise > 0) || r.pass_spp < 1) throw OptionError("truth: the noise target and pass spp must be > 0");
  const fs::path dir = r.cache_dir.empty() ? fs::path() : fs::path(r.cache_dir) / "truth" / TruthKey(r);
  if (!dir.empty() && fs::exists(dir / "truth.json") && fs::exists(dir / "truth.exr")) {
    std::ifstream in(dir / "truth.json");
    const nlohmann::json j = nlohmann::json::parse(in);
    Truth t;
    t.source = "path";
    t.path_traced = true;
    t.image = ReadImage((dir / "truth.exr").string());
    t.passes = j.at("passes");
    t.spp = j.at("spp");
    t.seconds = j.at("seconds");
    t.noise_rel_l1 = j.at("noise_rel_l1");
    t.noise_rel_l2 = j.at("noise_rel_l2");
    t.from_cache = true;
    t.label = PathLabel(t) + " (cached)";
    return t;
  }
  Truth t = RenderPathTruth(r);
  t.source = "path";
  t.path_traced = true;
  t.label = PathLabel(t);
  if (!dir.empty()) {
    fs::create_directories(dir);
    WriteEXR((dir / "truth.exr").string(), t.image);
    nlohmann::json j = {{"scene", r.scene},          {"passes", t.passes},
                        {"spp", t.spp},              {"seconds", t.seconds},
                        {"noise_rel_l1", t.noise_rel_l1}, {"noise_rel_l2", t.noise_rel_l2},
                        {"target_noise", r.noise}};
    WriteFileAtomically(dir / "truth.json", j.dump(2) + "\n");
  }
  return t;
}

double FireflyShare(const Image& truth, const Image& image) {
  if (!truth.SameSize(image) || truth.pixels.empty()) throw std::runtime_error("fireflies: image sizes differ");
  const double floor = 0.01 * truth.MeanLuminance();
  size_t off = 0, counted = 0;
  for (int y = 0; y < truth.height; ++y)
    for (int x = 0; x < truth.width; ++x) {
      double local = 0;
      int n = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= truth.width || yy >= truth.height) continue;
          const float l = truth.at(xx, yy).Luminance();
          if (!std::isfinite(l)) continue;
          local += double(l);
          ++n;
        }
      if (n == 0) continue;
      local /= n;
      const double v = double(image.at(x, y).Luminance());
      ++counted;
      if (v > 3 * local + floor || v < local / 3 - floor) ++off;
    }
  return counted ? double(off) / double(counted) : 0.0;
}

TruthMetrics CompareWithTruth(const Truth& truth, const Image& image) {
  const ErrorMetrics e = CompareImages(truth.image, image);
  TruthMetrics m;
  m.rel_l1 = e.rel_l1;
  m.rel_l2 = e.rel_l2;
  m.fireflies = FireflyShare(truth.image, image);
  return m;
}

}  // namespace lightfarm
