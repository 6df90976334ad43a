// Deterministic randomness. DESIGN.md: every random choice is seeded from (job seed, stage,
// task id, index) with a hash, never from a shared generator, so that results do not depend
// on thread count, task order or retries.
#pragma once

#include <cstdint>
#include <initializer_list>

namespace lightfarm {

// 64-bit finalizer of MurmurHash3 / splitmix64: full avalanche.
inline uint64_t MixBits(uint64_t v) {
  v ^= v >> 31;
  v *= 0x7fb5d329728ea185ULL;
  v ^= v >> 27;
  v *= 0x81dadef4bc2dd44dULL;
  v ^= v >> 33;
  return v;
}

// Hash of a sequence of integers, order-sensitive.
inline uint64_t HashSeed(std::initializer_list<uint64_t> parts) {
  uint64_t h = 0x9e3779b97f4a7c15ULL;
  for (uint64_t p : parts) h = MixBits(h ^ (p + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2)));
  return h;
}

// Stream identifiers that name which random decision a generator serves.
enum class RngStream : uint64_t {
  kCameraSample = 1,
  kEmitterSample = 2,
  kParticlePath = 3,
  kRowSample = 4,
  kColumnSample = 5,
  kClustering = 6,
  kCompletion = 7,
  kMedium = 8,
  kSlicing = 9,
  kPathSample = 10,  // the path tracer: one generator per (pixel, sample index)
  kCompensation = 11,  // the clamp compensation: one generator per (row, sample)
  kCausticPhoton = 12,  // caustic photon paths: one generator per path
  kCameraPilot = 13,  // camera-side pilot paths (receivers.cpp): one generator per pixel
  kNearSample = 14,  // adaptive-completion: near lights sampled per row
  kClampProbe = 15,  // the clamp-loss probe's light sets (clamp_probe.h): one per batch
  kSegmentCoverage = 16,  // coverage rays of media rows (receivers.cpp): one per camera sample
  kNearPilot = 17,  // the near-field rule's own light set (receivers.cpp, NearFieldLights)
};

// PCG32 (O'Neill 2014): small state, good statistics, cheap to seed per pixel / per path.
class Rng {
 public:
  Rng() { Seed(0, 0); }
  explicit Rng(uint64_t seed, uint64_t stream = 0) { Seed(seed, stream); }
  void Seed(uint64_t seed, uint64_t stream) {
    state_ = 0u;
    inc_ = (stream << 1u) | 1u;
    Next();
    state_ += seed;
    Next();
  }
  uint32_t Next() {
    uint64_t old = state_;
    state_ = old * 0x5851f42d4c957f2dULL + inc_;
    uint32_t xorshifted = static_cast<uint32_t>(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = static_cast<uint32_t>(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((~rot + 1u) & 31));
  }
  // Uniform in [0, 1): 24 random mantissa bits, so the result is never rounded up to 1.
  float Uniform() { return static_cast<float>(Next() >> 8) * 0x1p-24f; }
  double UniformDouble() {
    uint64_t hi = Next(), lo = Next();
    return static_cast<double>(((hi << 32) | lo) >> 11) * 0x1p-53;
  }
  // Uniform integer in [0, n) without modulo bias (Lemire's method).
  uint32_t UniformInt(uint32_t n) {
    uint64_t m = uint64_t(Next()) * uint64_t(n);
    uint32_t l = static_cast<uint32_t>(m);
    if (l < n) {
      uint32_t t = (0u - n) % n;
      while (l < t) {
        m = uint64_t(Next()) * uint64_t(n);
        l = static_cast<uint32_t>(m);
      }
    }
    return static_cast<uint32_t>(m >> 32);
  }

 private:
  uint64_t state_ = 0, inc_ = 1;
};

}  // namespace lightfarm
