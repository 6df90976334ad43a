// Whole files as bytes: scene files to upload, token files, images the coordinator streams.
#pragma once

#include <filesystem>
#include <string>

namespace lightfarm {

// The file's contents; throws std::runtime_error("cannot read PATH") when it cannot be opened.
std::string ReadFile(const std::string& path);

// Removes a directory and everything in it when the scope ends (errors ignored): the scene
// files a worker or embedded mode materializes for one job.
class ScopedRemoveDir {
 public:
  explicit ScopedRemoveDir(std::filesystem::path dir) : dir_(std::move(dir)) {}
  ~ScopedRemoveDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  ScopedRemoveDir(const ScopedRemoveDir&) = delete;
  ScopedRemoveDir& operator=(const ScopedRemoveDir&) = delete;

 private:
  std::filesystem::path dir_;
};

}  // namespace lightfarm
