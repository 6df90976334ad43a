// lightfarm-volpath-check: renders a scene with the independent volumetric path tracer of
// tests/oracle/volpath/path_tracer.h (what it is and what it handles is written there) and prints region
// means with their standard errors, to compare with a lightfarm render of the same scene.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "tests/oracle/volpath/path_tracer.h"
#include "common/image/image_io.h"
#include "common/util/error.h"

namespace lightfarm {
namespace {

int Main(int argc, char** argv) {
  CLI::App app{"Independent volumetric path tracer for validating lightfarm transport"};
  std::string scene_path, out_path, resolution;
  VolpathCheckOptions opt;
  app.add_option("scene", scene_path, "pbrt-v4 scene")->required();
  app.add_option("--out", out_path, "Output EXR")->required();
  app.add_option("--resolution", resolution, "WxH (default: the scene's Film)");
  app.add_option("--spp", opt.spp, "Samples per pixel");
  app.add_option("--maxdepth", opt.max_depth, "Override the scene's maxdepth");
  app.add_option("--seed", opt.seed, "Random seed");
  std::vector<std::string> regions;
  app.add_option("--region", regions,
                 "NAME:WxH+X+Y: also print the mean and its standard error over this pixel "
                 "rectangle (repeatable; oiiotool's geometry syntax)");
  app.add_option("--max-component", opt.max_component,
                 "Scale each sample so its largest channel is at most this (diagnostics: "
                 "pbrt-v4's RGBFilm maxcomponentvalue)");
  app.add_flag("--no-caustics", opt.no_emitted_after_specular,
               "Drop every caustic path L S+ (D|M) ... E (diagnostics)");
  app.add_flag("--no-direct-caustics", opt.no_direct_caustics,
               "Drop only caustics seen directly, L S+ X S* E with X the one non-specular "
               "camera vertex: what VPL/VRL rendering cannot form (diagnostics)");
  CLI11_PARSE(app, argc, argv);

  SceneBuildOptions build;
  if (!resolution.empty() && std::sscanf(resolution.c_str(), "%dx%d", &build.width, &build.height) != 2)
    throw OptionError("--resolution: expected WxH");
  build.filter = "box";
  std::unique_ptr<Scene> scene = Scene::Build(ParseSceneFile(scene_path), build);
  const PathTracedImage traced = RenderPathTraced(*scene, opt);
  const Image& img = traced.mean;
  const Image& var = traced.variance_of_mean;
  const int w = img.width, h = img.height;
  WriteEXR(out_path, img);
  // Mean over a pixel rectangle and the standard error of that mean (pixels independent).
  auto report = [&](const std::string& name, int x0, int y0, int rw, int rh) {
    double m[3] = {0, 0, 0}, v[3] = {0, 0, 0};
    int n = 0;
    for (int y = std::max(0, y0); y < std::min(h, y0 + rh); ++y)
      for (int x = std::max(0, x0); x < std::min(w, x0 + rw); ++x, ++n)
        for (int c = 0; c < 3; ++c) {
          m[c] += double(img.at(x, y)[c]);
          v[c] += double(var.at(x, y)[c]);
        }
    if (n == 0) throw OptionError("--region " + name + " is outside the image");
    std::printf("%-10s mean RGB (%.5f, %.5f, %.5f)  std. error (%.5f, %.5f, %.5f)\n", name.c_str(),
                m[0] / n, m[1] / n, m[2] / n, std::sqrt(v[0]) / n, std::sqrt(v[1]) / n,
                std::sqrt(v[2]) / n);
  };
  std::printf("maxdepth %d, %d spp, %dx%d\n", traced.max_depth, opt.spp, w, h);
  report("all", 0, 0, w, h);
  for (const std::string& r : regions) {
    size_t colon = r.find(':');
    int rw, rh, x0, y0;
    if (colon == std::string::npos ||
        std::sscanf(r.c_str() + colon + 1, "%dx%d+%d+%d", &rw, &rh, &x0, &y0) != 4)
      throw OptionError("--region " + r + ": expected NAME:WxH+X+Y");
    report(r.substr(0, colon), x0, y0, rw, rh);
  }
  return 0;
}

}  // namespace
}  // namespace lightfarm

int main(int argc, char** argv) {
  try {
    return lightfarm::Main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lightfarm-volpath-check: %s\n", e.what());
    return 1;
  }
}
