#include "common/util/file.h"

#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>

namespace lightfarm {

std::string ReadFile(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot read " + path);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

std::filesystem::path TemporaryPathBeside(const std::filesystem::path& target) {
  static std::atomic<uint64_t> counter{0};
  const std::string name = "." + target.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                           std::to_string(counter.fetch_add(1));
  return target.parent_path() / name;
}

void ReplaceFileAtomically(const std::filesystem::path& target,
                           const std::function<void(const std::filesystem::path& temporary)>& write) {
  const std::filesystem::path temporary = TemporaryPathBeside(target);
  auto fail = [&](const std::string& why) {
    std::error_code ignored;
    std::filesystem::remove(temporary, ignored);
    throw std::runtime_error("cannot write \"" + target.string() + "\": " + why);
  };
  try {
    write(temporary);
  } catch (const std::exception& e) {
    fail(e.what());
  }
  std::error_code ec;
  std::filesystem::rename(temporary, target, ec);
  if (ec) fail("rename from temporary file failed: " + ec.message());
}

void WriteFileAtomically(const std::filesystem::path& target, std::string_view data) {
  ReplaceFileAtomically(target, [&](const std::filesystem::path& temporary) {
    errno = 0;
    std::ofstream f(temporary, std::ios::binary);
    f.write(data.data(), std::streamsize(data.size()));
    f.close();
    if (!f) throw std::runtime_error(errno != 0 ? std::strerror(errno) : "write failed");
  });
}

}  // namespace lightfarm
