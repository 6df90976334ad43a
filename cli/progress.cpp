#include "cli/progress.h"

#include <unistd.h>

#include <cstdio>

namespace lightfarm::cli {

ProgressBar::ProgressBar()
    : enabled_(isatty(STDERR_FILENO) != 0), start_(std::chrono::steady_clock::now()) {}

void ProgressBar::Update(const std::string& label, size_t done, size_t total) {
  if (!enabled_ || total == 0) return;
  auto now = std::chrono::steady_clock::now();
  if (drawn_ && done < total && now - last_draw_ < std::chrono::milliseconds(100)) return;
  last_draw_ = now;
  drawn_ = true;
  double frac = double(done) / double(total);
  double elapsed = std::chrono::duration<double>(now - start_).count();
  double eta = frac > 0 ? elapsed * (1 - frac) / frac : 0;
  const int width = 30;
  int filled = int(frac * width);
  std::string bar(size_t(filled), '#');
  bar.resize(width, '.');
  std::fprintf(stderr, "\r%-8s [%s] %5.1f%%  %zu/%zu  elapsed %.1fs  eta %.1fs ", label.c_str(),
               bar.c_str(), 100 * frac, done, total, elapsed, eta);
  std::fflush(stderr);
}

void ProgressBar::Finish() {
  if (enabled_ && drawn_) std::fprintf(stderr, "\n");
  drawn_ = false;
}

}  // namespace lightfarm::cli
