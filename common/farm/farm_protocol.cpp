#include "common/farm/farm_protocol.h"

#include <filesystem>

namespace lightfarm {

bool IsSafeScenePath(const std::string& p) {
  if (p.empty() || p.size() > 4096 || p[0] == '/' || p.find('\0') != std::string::npos) return false;
  // Components, not substrings: "a/../b" escapes, "a..b.png" does not. A trailing '/' gives an
  // empty last component (a directory, not a file).
  for (const auto& part : std::filesystem::path(p))
    if (part == ".." || part == "." || part.empty()) return false;
  return true;
}

}  // namespace lightfarm
