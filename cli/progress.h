// A one-line progress bar with ETA on a terminal (stderr); silent when stderr is not a TTY.
#pragma once

#include <chrono>
#include <string>

namespace lightfarm::cli {

class ProgressBar {
 public:
  ProgressBar();
  void Update(const std::string& label, size_t done, size_t total);
  void Finish();

 private:
  bool enabled_ = false;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
};

}  // namespace lightfarm::cli
