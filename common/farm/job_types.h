// The farm's job vocabulary as plain C++ (the scheduler keeps its state in these; the protocol's
// messages are converted at the service edge, proto_convert.h).
#pragma once

#include <string>
#include <vector>

namespace lightfarm {

// A job's life. The values are the wire's (v1::JobState) and the ones the coordinator's store
// keeps, so neither a restart nor an old database reads them differently.
enum class JobState : int { kQueued = 1, kPlanning = 2, kRunning = 3, kDone = 4, kFailed = 5, kCancelled = 6 };

const char* JobStateName(JobState state);  // "queued", "running", ...
inline bool IsTerminal(JobState state) {
  return state == JobState::kDone || state == JobState::kFailed || state == JobState::kCancelled;
}

// A scene as submitted: its files by content hash, at paths relative to the scene directory.
struct SceneFileRef {
  std::string path;
  std::string sha256;  // lower-case hex
};
struct SceneManifest {
  std::string root;  // the root .pbrt file's path among `files`
  std::vector<SceneFileRef> files;
  // What identifies the scene's content wherever it is materialized (SceneCache's key): the
  // root's path and every file's path and hash.
  std::string ContentKey() const {
    std::string key = root;
    for (const SceneFileRef& f : files) key += "\n" + f.path + " " + f.sha256;
    return key;
  }
  // The root file's hash ("" when it is not among the files).
  std::string RootSha256() const {
    for (const SceneFileRef& f : files)
      if (f.path == root) return f.sha256;
    return "";
  }
};

}  // namespace lightfarm
