#include "coordinator/storage_guard.h"

#include <spdlog/spdlog.h>

#include <filesystem>
#include <sstream>

namespace lightfarm {

namespace fs = std::filesystem;

bool StorageGuard::Low() const {
  std::error_code ec;
  const fs::space_info space = fs::space(dir_, ec);
  return !ec && space.available < min_free_bytes_;
}

std::string StorageGuard::FullMessage() const {
  std::error_code ec;
  const fs::space_info space = fs::space(dir_, ec);
  std::string what;
  {
    std::lock_guard lock(mu_);
    what = what_;
  }
  std::ostringstream os;
  os << "the coordinator's disk is full (";
  if (!ec) os << (space.available >> 20) << " MiB free under " << dir_ << "; ";
  os << "new work needs " << (min_free_bytes_ >> 20) << " MiB, --min-free-mb)";
  if (!what.empty()) os << ": " << what;
  os << ". Accepted jobs wait and resume when space returns";
  return os.str();
}

void StorageGuard::NoteFull(const std::string& what) {
  if (!wait_for_space_) {
    spdlog::error("state directory {} is full: {}", dir_, what);
    return;
  }
  {
    std::lock_guard lock(mu_);
    what_ = what;
  }
  if (!full_.exchange(true)) {
    if (full_events_) ++*full_events_;
    spdlog::error("state directory {} is full ({}): new jobs are refused and leases paused until space returns",
                  dir_, what);
  }
}

bool StorageGuard::IsFault(const std::exception& e) const {
  if (!wait_for_space_) return false;
  if (dynamic_cast<const StorageFull*>(&e)) return true;
  if (const auto* fe = dynamic_cast<const fs::filesystem_error*>(&e); fe && IsNoSpaceErrno(fe->code().value()))
    return true;
  // Image writers and the like report a failed write in their own words: while space is low,
  // a write error is the disk's, not the job's.
  return Low();
}

bool StorageGuard::CheckRecovered(const std::function<bool()>& can_write) {
  const auto now = std::chrono::steady_clock::now();
  if (now - checked_ < std::chrono::milliseconds(500)) return false;
  checked_ = now;
  const bool low = Low();
  if (!full_) {
    if (low) NoteFull("free space is below --min-free-mb");
    return false;
  }
  // Space is back when it is above the reserve and a write of a typical blob succeeds.
  if (low || !can_write()) return false;
  full_ = false;
  spdlog::warn("state directory {} has space again: resuming", dir_);
  return true;
}

}  // namespace lightfarm
