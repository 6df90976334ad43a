#include "common/scene/scene_cache.h"

#include <filesystem>

namespace lightfarm {

namespace fs = std::filesystem;

namespace {

std::string Absolute(const std::string& p) { return fs::absolute(p).lexically_normal().string(); }

// `path` moved from under `from` to under `to`; unchanged when it is not under `from`.
std::string Moved(const std::string& path, const fs::path& from, const fs::path& to) {
  const fs::path rel = fs::absolute(path).lexically_normal().lexically_relative(from);
  if (rel.empty() || *rel.begin() == "..") return path;
  return (to / rel).lexically_normal().string();
}

}  // namespace

SceneDescription RebaseScene(const SceneDescription& desc, const std::string& from_dir, const std::string& to_dir,
                             const std::string& root) {
  SceneDescription out = desc;
  const fs::path from = Absolute(from_dir), to = Absolute(to_dir);
  out.root_file = (to / root).lexically_normal().string();
  const std::string parent = fs::path(out.root_file).parent_path().string();
  out.base_dir = parent.empty() ? "." : parent;
  for (std::string& f : out.files) f = Moved(f, from, to);
  return out;
}

SceneCache& SceneCache::Process() {
  // Two: the coordinator plans two jobs at once by default (--max-active-jobs), a worker runs
  // one job's tasks at a time and may be handed the next job's first.
  static SceneCache cache(2);
  return cache;
}

void SceneCache::InsertLocked(Entry entry) {
  for (auto it = entries_.begin(); it != entries_.end(); ++it)
    if (it->key == entry.key) {
      entries_.erase(it);
      break;
    }
  entries_.push_front(std::move(entry));
  while (entries_.size() > capacity_) entries_.pop_back();
}

std::shared_ptr<const SceneDescription> SceneCache::Get(const std::string& key, const std::string& dir,
                                                        const std::string& root) {
  const std::string abs_dir = Absolute(dir);
  Entry found;
  {
    std::lock_guard lock(mu_);
    for (auto it = entries_.begin(); it != entries_.end(); ++it) {
      if (it->key != key) continue;
      entries_.splice(entries_.begin(), entries_, it);  // most recently used
      found = entries_.front();
      ++hits_;
      break;
    }
  }
  if (found.desc) {
    if (found.dir == abs_dir && found.root == root) return found.desc;
    // Kept where it was last asked for: the next pass of the same job asks there again.
    auto rebased = std::make_shared<const SceneDescription>(RebaseScene(*found.desc, found.dir, abs_dir, root));
    std::lock_guard lock(mu_);
    InsertLocked(Entry{key, abs_dir, root, rebased});
    return rebased;
  }
  // Parsed outside the lock: another role may parse the same scene meanwhile (both results are
  // the same description; the later one is kept).
  auto desc = std::make_shared<const SceneDescription>(ParseSceneFile((fs::path(dir) / root).string()));
  std::lock_guard lock(mu_);
  ++parses_;
  InsertLocked(Entry{key, abs_dir, root, desc});
  return desc;
}

void SceneCache::Put(const std::string& key, const std::string& dir, const std::string& root, SceneDescription desc) {
  std::lock_guard lock(mu_);
  InsertLocked(Entry{key, Absolute(dir), root, std::make_shared<const SceneDescription>(std::move(desc))});
}

uint64_t SceneCache::parses() const {
  std::lock_guard lock(mu_);
  return parses_;
}

uint64_t SceneCache::hits() const {
  std::lock_guard lock(mu_);
  return hits_;
}

}  // namespace lightfarm
