// Writes the generated part of the fuzz seed corpus: one valid encoding of each farm message
// (current serialize version) and small PLY meshes in every format the reader knows.
// Usage: fuzz_make_seeds DIR   (creates DIR/decode_farm and DIR/read_ply)
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/render/serialize.h"
#include "common/scene/ply.h"

namespace fs = std::filesystem;
using namespace lightfarm;

namespace {

void WriteBytes(const fs::path& path, const Bytes& bytes) {
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIR\n", argv[0]);
    return 2;
  }
  const fs::path dir = argv[1];
  fs::create_directories(dir / "decode_farm");
  fs::create_directories(dir / "read_ply");

  SubMatrixTask task;
  task.stage = 1;
  task.task_id = 3;
  task.seed = 42;
  task.rows = {0, 1, 2, 7};
  task.neighbors = {2, 4};
  WriteBytes(dir / "decode_farm" / "task", SerializeTask(task));

  TaskOutput output;
  output.row_sums = {RGBAccum{0.5, 0.25, 1.0}, RGBAccum{0, 0, 0}};
  output.payload = {1, 2, 3};
  output.counters.elements = 10;
  output.counters.shadow_rays = 4;
  output.stats = {{"clusters", 2}};
  WriteBytes(dir / "decode_farm" / "task_output", SerializeTaskOutput(output));

  LightSet lights;
  VirtualLight area, surface, point, distant;
  area.kind = VirtualLightKind::kAreaVPL;
  area.power = RGB(1, 2, 3);
  surface.kind = VirtualLightKind::kSurfaceVPL;
  surface.depth = 2;
  surface.caustic = true;
  point.kind = VirtualLightKind::kPoint;
  point.spot = true;
  point.cos_falloff_start = 0.9f;
  point.cos_falloff_end = 0.8f;
  distant.kind = VirtualLightKind::kDirectional;
  lights.lights = {area, surface, point, distant};
  lights.stats.particle_paths = 5;
  WriteBytes(dir / "decode_farm" / "light_set", SerializeLightSet(lights));

  ReceiverSet receivers;
  receivers.width = 2;
  receivers.height = 1;
  receivers.spp = 1;
  for (int32_t s = 0; s < 2; ++s) {
    CameraSample cs;
    cs.pixel = uint32_t(s);
    cs.weight = 1;
    if (s == 0) cs.first_point = 0, cs.point_count = 1;
    receivers.samples.push_back(cs);
  }
  ShadingPoint sp;
  sp.throughput = RGB(1);
  receivers.points.push_back(sp);
  WriteBytes(dir / "decode_farm" / "receiver_set", SerializeReceiverSet(receivers));

  PlyMesh mesh;
  mesh.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  WritePly((dir / "read_ply" / "quad_ascii.ply").string(), mesh, "ascii");
  WritePly((dir / "read_ply" / "quad_binary.ply").string(), mesh, "binary_little_endian");
  mesh.normals.assign(4, Vec3(0, 0, 1));
  mesh.uvs = {Vec2(0, 0), Vec2(1, 0), Vec2(1, 1), Vec2(0, 1)};
  WritePly((dir / "read_ply" / "quad_attributes_ascii.ply").string(), mesh, "ascii");
  WritePly((dir / "read_ply" / "quad_attributes_binary.ply").string(), mesh,
           "binary_little_endian");
  return 0;
}
