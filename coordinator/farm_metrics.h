// What the coordinator counts and how it exposes it: counters bumped where things happen (plain
// atomics, no lock), a snapshot of the scheduler's gauges taken under its lock, and the
// Prometheus text exposition of both (the HTTP server serves it at /metrics).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>

namespace lightfarm {

struct FarmCounters {
  std::atomic<uint64_t> submitted{0};       // jobs accepted
  std::atomic<uint64_t> leases{0};          // task leases granted
  std::atomic<uint64_t> lease_polls{0};     // LeaseTask calls
  std::atomic<uint64_t> completed{0};       // task results accepted
  std::atomic<uint64_t> duplicates{0};      // duplicate or stale results ignored
  std::atomic<uint64_t> failed{0};          // failed attempts (expired leases included)
  std::atomic<uint64_t> expired{0};         // leases that expired without a heartbeat
  std::atomic<uint64_t> storage_full{0};    // times the state directory filled up
  std::atomic<uint64_t> verified{0};        // tasks two workers agreed on bit for bit
  std::atomic<uint64_t> mismatches{0};      // verified tasks whose first two results differed
  std::atomic<uint64_t> repairs{0};         // jobs sent back to recompute
  std::atomic<uint64_t> scrubbed_bytes{0};  // bytes the scrub re-hashed
  std::atomic<uint64_t> scrub_passes{0};    // complete scrub passes
  std::atomic<uint64_t> gc_removed{0};      // blobs the collection removed
  std::atomic<uint64_t> gc_removed_bytes{0};
  std::atomic<uint64_t> deleted{0};         // jobs deleted (request or retention)
};

struct FarmGauges {
  std::map<std::string, int> jobs_by_state;  // JobStateName -> count
  uint64_t tasks_pending = 0, tasks_leased = 0;
  size_t workers = 0;
  bool storage_full = false;
  uint64_t blobs_corrupted = 0;
};

std::string PrometheusText(const FarmCounters& counters, const FarmGauges& gauges);

}  // namespace lightfarm
