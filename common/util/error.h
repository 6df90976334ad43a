// Errors that carry where they come from. The CLI's main and the gRPC service boundary are the
// only places that turn these into exit codes / statuses (see STYLE.md, Embree).
#pragma once

#include <stdexcept>
#include <string>

namespace lightfarm {

// A position in a scene file, for messages like "scene.pbrt:41: unknown parameter ...".
struct FileLoc {
  std::string file;
  int line = 0;
  int column = 0;
  std::string ToString() const {
    if (file.empty()) return "<input>";
    return line > 0 ? file + ":" + std::to_string(line) : file;
  }
};

// Malformed or unsupported scene input. what() is "file:line: message".
class SceneError : public std::runtime_error {
 public:
  SceneError(const FileLoc& loc, const std::string& message)
      : std::runtime_error(loc.ToString() + ": " + message), loc_(loc), message_(message) {}
  const FileLoc& loc() const { return loc_; }
  const std::string& message() const { return message_; }

 private:
  FileLoc loc_;
  std::string message_;
};

// Invalid user-supplied option (CLI flag, --param, job setting).
class OptionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace lightfarm
