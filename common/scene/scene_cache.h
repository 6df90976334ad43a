// Parsed scenes kept per process, so that a job's scene is parsed once however many roles read
// it (the client, the coordinator and the worker of one embedded process) and however many
// passes a progressive job runs. Entries are keyed by the scene's content (the farm's manifest:
// every file's relative path and SHA-256, SceneManifest::ContentKey), so a description parsed
// from one directory serves the same files materialized in another: it is handed out rebased
// there (base_dir, root_file and files under the new directory). It holds at most `capacity`
// descriptions (the least recently used goes first): a process keeps that many scenes' parsed
// text (inline meshes included) beyond their jobs. Thread-safe.
#pragma once

#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

#include "common/scene/scene_description.h"

namespace lightfarm {

class SceneCache {
 public:
  explicit SceneCache(size_t capacity = 4) : capacity_(capacity) {}

  // The cache every role of this process shares.
  static SceneCache& Process();

  // The scene whose root file is `root` (relative to `dir`) with the content `key`: the cached
  // description rebased to `dir`, or parsed from dir/root (and kept) when none is cached.
  // Throws SceneError as ParseSceneFile does.
  std::shared_ptr<const SceneDescription> Get(const std::string& key, const std::string& dir, const std::string& root);
  // Keeps a description the caller parsed itself (from dir/root), e.g. the client that uploads it.
  void Put(const std::string& key, const std::string& dir, const std::string& root, SceneDescription desc);

  uint64_t parses() const;  // descriptions parsed by Get
  uint64_t hits() const;    // descriptions Get found cached

 private:
  struct Entry {
    std::string key;
    std::string dir;  // where it was parsed (absolute)
    std::string root;
    std::shared_ptr<const SceneDescription> desc;
  };
  void InsertLocked(Entry entry);

  size_t capacity_;
  mutable std::mutex mu_;
  std::list<Entry> entries_;  // most recently used first
  uint64_t parses_ = 0, hits_ = 0;
};

// `desc`, parsed with its root at from_dir/root, as if parsed at to_dir/root: the directory
// relative names resolve against, the root's path and every recorded file under from_dir move
// to to_dir (files elsewhere stay where they are).
SceneDescription RebaseScene(const SceneDescription& desc, const std::string& from_dir, const std::string& to_dir,
                             const std::string& root);

}  // namespace lightfarm
