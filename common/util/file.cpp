#include "common/util/file.h"

#include <fstream>
#include <iterator>
#include <stdexcept>

namespace lightfarm {

std::string ReadFile(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot read " + path);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

}  // namespace lightfarm
