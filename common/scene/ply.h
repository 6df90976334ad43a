// Triangle meshes in the PLY format (Turk 1994): ASCII, binary_little_endian and
// binary_big_endian. The reader treats every byte as untrusted: element counts are checked
// against the file size before anything is allocated, and every malformed file ends in a
// SceneError naming the file and the header line or element index, never in a crash.
#pragma once

#include <string>
#include <vector>

#include "common/util/math.h"

namespace lightfarm {

struct PlyMesh {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;  // empty or same size as positions
  std::vector<Vec2> uvs;      // empty or same size as positions
  std::vector<int> indices;   // triangles (quads and convex polygons fan-triangulated)
};

// Largest polygon ReadPly accepts; bigger faces are almost always corrupt counts.
inline constexpr int kPlyMaxPolygonVertices = 64;

// Reads the "vertex" element (x y z required; nx ny nz, and u v / s t / texture_u texture_v
// optional) and the "face" element (list "vertex_indices" or "vertex_index"). Other
// properties and elements are skipped. Throws SceneError: header problems carry the header
// line, data problems line 0 and the element index in the message.
PlyMesh ReadPly(const std::string& path);

// Writes a mesh (for tests and tools). format: "ascii" or "binary_little_endian".
// Throws SceneError for an unknown format, an inconsistent mesh or an unwritable file.
void WritePly(const std::string& path, const PlyMesh& mesh, const std::string& format);

}  // namespace lightfarm
