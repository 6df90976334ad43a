// Whole files as bytes: scene files to upload, token files, images the coordinator streams; and
// files replaced atomically, so that a reader (an image viewer, a second process, a restart after
// a crash) sees the old file or the new one, never half of one.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <string_view>

namespace lightfarm {

// The file's contents; throws std::runtime_error("cannot read PATH") when it cannot be opened.
std::string ReadFile(const std::string& path);

// A temporary name beside `target` (the same directory, so rename() is atomic on POSIX), unique
// per process and call: ".NAME.tmp-PID-N".
std::filesystem::path TemporaryPathBeside(const std::filesystem::path& target);

// Replaces `target` by what write(temporary) writes to a temporary file beside it. When write
// throws or the rename fails, the temporary file is removed, `target` is untouched and
// std::runtime_error("cannot write \"TARGET\": WHY") is thrown.
void ReplaceFileAtomically(const std::filesystem::path& target,
                           const std::function<void(const std::filesystem::path& temporary)>& write);

// Replaces `target` by the bytes `data`, atomically as above.
void WriteFileAtomically(const std::filesystem::path& target, std::string_view data);

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
