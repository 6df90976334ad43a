// What the coordinator, its workers and its clients must agree on, whichever side of the wire
// they are: the worker protocol's version, the rule a scene file's path follows and the size of
// a stream's chunks. Both sides include this
// (neither includes the other), so a job the coordinator accepts is one every worker can run.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace lightfarm {

// Workers and coordinator must speak the same worker protocol and task encodings
// (serialize.h's kSerializeVersion moves with it). 2: film methods (path); 3: caustic counters;
// 4: camera-side paths; 5: coverage paths (receiver stats).
inline constexpr uint32_t kWorkerProtocolVersion = 5;

// Streamed data (blob uploads, scene downloads, task results) travels in chunks of this size, far
// below the servers' message limit, so a message never nears it whatever the file.
inline constexpr size_t kChunkBytes = size_t(1) << 20;

// A scene file's path as a manifest names it: relative, at most 4096 bytes, no NUL, and no
// component that is empty, "." or ".." (a name that merely contains two dots, "tex/a..b.png",
// is fine), so that materialized under any directory it stays inside it.
bool IsSafeScenePath(const std::string& path);

}  // namespace lightfarm
