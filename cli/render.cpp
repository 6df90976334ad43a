// `lightfarm render SCENE ...`: renders in this process and writes EXR + PNG + stats JSON.
#include <tbb/global_control.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <regex>

#include "cli/commands.h"
#include "cli/progress.h"
#include "common/farm/render_job.h"
#include "common/image/image_io.h"
#include "common/util/error.h"

namespace lightfarm::cli {

namespace {

struct RenderArgs {
  std::string scene;
  std::string method = "brute";
  std::string out = "out/render.exr";
  std::string stats;
  std::string resolution;
  std::string filter;
  int spp = 1;
  long long lights = 10000;
  unsigned long long seed = 0;
  int threads = 0;
  int workers = 1;
  std::vector<std::string> params;
  bool quiet = false;
};

void ParseResolution(const std::string& s, int* w, int* h) {
  std::smatch m;
  static const std::regex re(R"(^(\d{1,6})x(\d{1,6})$)");
  if (!std::regex_match(s, m, re))
    throw OptionError("--resolution expects WxH (e.g. 256x256), got \"" + s + "\"");
  *w = std::stoi(m[1]);
  *h = std::stoi(m[2]);
  if (*w < 1 || *h < 1 || *w > 65536 || *h > 65536)
    throw OptionError("--resolution " + s + " is out of range (1..65536 per axis)");
}

// Writes via a temporary file and rename, so a failed run leaves no partial file behind.
void WriteTextAtomically(const std::string& path, const std::string& text) {
  std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp);
    if (!f) throw std::runtime_error("cannot write " + path);
    f << text;
    if (!f) throw std::runtime_error("cannot write " + path);
  }
  std::filesystem::rename(tmp, path);
}

void RunRender(const RenderArgs& a) {
  RenderSettings s;
  s.method = a.method;
  if (!a.resolution.empty()) ParseResolution(a.resolution, &s.width, &s.height);
  s.filter = a.filter;
  s.spp = a.spp;
  s.lights = size_t(a.lights);
  s.seed = a.seed;
  s.params = a.params;
  if (a.out.size() < 5 || a.out.substr(a.out.size() - 4) != ".exr")
    throw OptionError("--out must name an .exr file, got \"" + a.out + "\"");
  if (a.workers != 1)
    throw OptionError("--workers: the embedded farm arrives with the farm issue; only 1 for now");
  std::filesystem::path out_path(a.out);
  if (out_path.has_parent_path()) std::filesystem::create_directories(out_path.parent_path());

  std::unique_ptr<tbb::global_control> limit;
  if (a.threads > 0)
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  size_t(a.threads));
  ProgressBar bar;
  RenderOutput out = RenderScene(a.scene, s, [&](const std::string& phase, size_t done, size_t total) {
    if (!a.quiet) bar.Update(phase, done, total);
  });
  bar.Finish();
  WriteEXR(a.out, out.image);
  std::string png = a.out.substr(0, a.out.size() - 4) + ".png";
  WritePNG(png, out.image);
  if (!a.stats.empty()) WriteTextAtomically(a.stats, out.stats.dump(2) + "\n");
  if (!a.quiet) {
    std::fprintf(stderr, "%s: %s, %zu lights, %.2fs -> %s\n", a.scene.c_str(),
                 out.stats["method"].get<std::string>().c_str(),
                 out.stats["lights"]["total"].get<size_t>(),
                 out.stats["time"]["total_s"].get<double>(), a.out.c_str());
  }
}

}  // namespace

void AddRenderCommand(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand("render", "Render a pbrt-v4 scene in this process");
  cmd->add_option("scene", args->scene, "pbrt-v4 scene file")->required()->check(CLI::ExistingFile);
  cmd->add_option("--method", args->method, "Gather method (brute, ...)");
  cmd->add_option("--out", args->out, "Output EXR (a tone-mapped PNG is written beside it)");
  cmd->add_option("--stats", args->stats, "Write stats JSON here");
  cmd->add_option("--resolution", args->resolution, "WxH (default: the scene's Film)");
  cmd->add_option("--filter", args->filter, "Override the scene's pixel filter")
      ->check(CLI::IsMember({"box", "triangle", "gaussian", "mitchell", "sinc"}));
  cmd->add_option("--spp", args->spp, "Camera samples per pixel")->check(CLI::Range(1, 4096));
  cmd->add_option("--lights", args->lights, "Number of virtual lights")
      ->check(CLI::Range(1LL, 100000000LL));
  cmd->add_option("--seed", args->seed, "Random seed");
  cmd->add_option("--threads", args->threads, "Worker threads (0 = all cores)")
      ->check(CLI::Range(0, 4096));
  cmd->add_option("--workers", args->workers, "Workers of the embedded farm")
      ->check(CLI::Range(1, 256));
  cmd->add_option("--param", args->params, "Method/renderer parameter KEY=VALUE (repeatable)");
  cmd->add_flag("--quiet", args->quiet, "No progress output");
  cmd->callback([args] { RunRender(*args); });
}

}  // namespace lightfarm::cli
