// Every message about degenerate geometry names the shape: the Shape directive's file:line (and
// the PLY file for plymesh data). Zero-area triangles are dropped with a warning (real meshes
// hold them: see docs/robustness.md); NaN/Inf in input arrays are errors.
#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <limits>
#include <sstream>
#include <string>

#include "common/render/render_job.h"
#include "common/scene/ply.h"
#include "common/util/error.h"
#include "tests/stability/stability_util.h"

namespace lightfarm {
namespace test_degenerate_geometry_messages {

using testing::TempDir;

const char* kHeader =
    "Film \"rgb\" \"integer xresolution\" [8] \"integer yresolution\" [8]\n"
    "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\nWorldBegin\n"
    "LightSource \"point\" \"rgb I\" [5 5 5] \"point3 from\" [0 0 3]\n";  // the world starts on line 6

// Captures what spdlog logs while it lives (the default logger is swapped and restored).
class LogCapture {
 public:
  LogCapture() : previous_(spdlog::default_logger()) {
    auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(stream_);
    sink->set_pattern("%l %v");
    spdlog::set_default_logger(std::make_shared<spdlog::logger>("capture", sink));
  }
  ~LogCapture() { spdlog::set_default_logger(previous_); }
  std::string text() const { return stream_.str(); }

 private:
  std::shared_ptr<spdlog::logger> previous_;
  std::ostringstream stream_;
};

RenderOutput Render(const TempDir& dir, const std::string& world) {
  RenderSettings s;
  s.lights = 20;
  return RenderScene(dir.Write("scene.pbrt", kHeader + world), s);
}

void ExpectContains(const std::string& text, const std::vector<std::string>& pieces) {
  for (const std::string& piece : pieces)
    EXPECT_NE(text.find(piece), std::string::npos) << "\"" << text << "\" lacks \"" << piece << "\"";
}

TEST(DegenerateGeometryMessages, DroppedZeroAreaTrianglesAreAWarningNamingTheShape) {
  TempDir dir;
  std::string log;
  {
    LogCapture capture;
    const RenderOutput out = Render(
        dir, "Shape \"trianglemesh\" \"point3 P\" [-1 -1 0 1 -1 0 1 1 0 -1 1 0  0 0 0]"
             " \"integer indices\" [0 1 2 0 2 3  0 0 1  4 4 4  0 2 0]\n");
    testing::ExpectFiniteBounded(out.image, 1e3f);
    log = capture.text();
  }
  ExpectContains(log, {"warning", "scene.pbrt:6", "Shape \"trianglemesh\"", "dropped 3 zero-area"});
  // A mesh of nothing but degenerate triangles is skipped, named the same way.
  {
    LogCapture capture;
    Render(dir, "\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 1 1 2 2 2] \"integer indices\" [0 1 2]\n");
    log = capture.text();
  }
  ExpectContains(log, {"scene.pbrt:7", "Shape \"trianglemesh\"", "skipped"});
}

TEST(DegenerateGeometryMessages, PlyMeshWarningsAndErrorsNameTheShapeAndTheFile) {
  TempDir dir;
  PlyMesh mesh;
  mesh.positions = {Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0), Vec3(-1, -1, 0)};
  mesh.indices = {0, 1, 2, 0, 3, 1};  // the second triangle repeats vertex 0's position
  WritePly(dir.Path("mesh.ply"), mesh, "binary_little_endian");
  {
    LogCapture capture;
    Render(dir, "Shape \"plymesh\" \"string filename\" \"mesh.ply\"\n");
    ExpectContains(capture.text(), {"scene.pbrt:6", "Shape \"plymesh\"", "dropped 1 zero-area"});
  }
  // NaN and Inf positions, normals and texture coordinates: a SceneError naming the Shape
  // directive, the PLY file, the vertex and the attribute.
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  for (int which = 0; which < 3; ++which)
    for (float bad : {nan, inf, -inf}) {
      PlyMesh m = mesh;
      m.normals.assign(4, Vec3(0, 0, 1));
      m.uvs.assign(4, Vec2(0.5f, 0.5f));
      if (which == 0) m.positions[2].x = bad;
      if (which == 1) m.normals[1].z = bad;
      if (which == 2) m.uvs[3].y = bad;
      WritePly(dir.Path("bad.ply"), m, "binary_little_endian");
      try {
        Render(dir, "Shape \"plymesh\" \"string filename\" \"bad.ply\"\n");
        ADD_FAILURE() << "no error for a non-finite value in array " << which;
      } catch (const SceneError& e) {
        // e.g. "…/scene.pbrt:6: Shape "plymesh": …/bad.ply: vertex 1: non-finite normal (0, 0, nan)"
        ExpectContains(e.what(), {"scene.pbrt:6", "Shape \"plymesh\"", "bad.ply", "vertex",
                                  which == 0 ? "position" : which == 1 ? "normal" : "texture"});
      }
    }
}

}  // namespace test_degenerate_geometry_messages
}  // namespace lightfarm
