// Whether the coordinator's state directory can take more writes. A write refused for want of
// space (or free space below the reserve) marks it full: new work pauses (RESOURCE_EXHAUSTED
// for submits and uploads, no leases, no planning) until a periodic check sees space again and a
// test write succeeds. Not the scheduler's business how that is decided: it asks full() and
// reacts to Check() (coordinator.cpp resumes the paused jobs).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <string>

#include "coordinator/storage_full.h"

namespace lightfarm {

class StorageGuard {
 public:
  // `wait_for_space` false (an embedded render): a storage fault is an ordinary error that
  // fails its job, and the directory is never marked full. `full_events` counts the times it
  // became full (for /metrics).
  StorageGuard(std::string dir, uint64_t min_free_bytes, bool wait_for_space, std::atomic<uint64_t>* full_events)
      : dir_(std::move(dir)), min_free_bytes_(min_free_bytes), wait_for_space_(wait_for_space),
        full_events_(full_events) {}

  bool full() const { return full_; }
  // Free space under the directory is below the reserve (--min-free-mb).
  bool Low() const;
  // For the client: how full it is, what failed, and that accepted jobs wait.
  std::string FullMessage() const;
  // A write failed for want of space (or space ran low): marks the directory full.
  void NoteFull(const std::string& what);
  // An error from planning or combining: a storage fault (pause and retry later) or not.
  bool IsFault(const std::exception& e) const;
  // The periodic check (at most every 500 ms): marks the directory full when space is low;
  // true when it was full and space is back (above the reserve and `can_write` succeeds).
  bool CheckRecovered(const std::function<bool()>& can_write);

 private:
  const std::string dir_;
  const uint64_t min_free_bytes_;
  const bool wait_for_space_;
  std::atomic<uint64_t>* full_events_;
  std::atomic<bool> full_{false};
  mutable std::mutex mu_;
  std::string what_;  // the write that failed, or the free space seen (mu_)
  std::chrono::steady_clock::time_point checked_;  // CheckRecovered's caller serializes it
};

}  // namespace lightfarm
