// `lightfarm render SCENE ...`: renders on an embedded farm (a coordinator and --workers workers
// in this process, over in-process gRPC channels: the farm's code path) and writes EXR + PNG +
// stats JSON. The image is bit-identical to RenderScene and to the farm with the same seed.
#include <tbb/global_control.h>

#include <cstdio>
#include <filesystem>
#include <iostream>

#include "cli/commands.h"
#include "cli/farm_options.h"
#include "cli/progress.h"
#include "cli/render_options.h"
#include "cli/target_error.h"
#include "common/evaluation/clamp_probe.h"
#include "common/image/image_io.h"
#include "common/util/error.h"
#include "common/util/file.h"
#include "cli/embedded_farm.h"

namespace lightfarm::cli {

namespace {

struct RenderArgs {
  std::string scene;
  RenderOptionArgs render;
  TargetErrorArgs target;
  std::string out = "out/render.exr";
  std::string stats;
  int threads = 0;
  int workers = 1;
  bool quiet = false;
};

void RunRender(const RenderArgs& a) {
  RenderSettings s = ToRenderSettings(a.render);
  TargetErrorArgs target_args = a.target;
  target_args.lights_given = a.render.lights > 0;
  const TargetErrorPlan target = ApplyTargetError(target_args, a.scene, &s);
  const int clamp_probe = TakeClampProbe(&s);
  if (a.out.size() < 5 || a.out.substr(a.out.size() - 4) != ".exr")
    throw OptionError("--out must name an .exr file, got \"" + a.out + "\"");
  RequireImageIo();
  std::filesystem::path out_path(a.out);
  if (out_path.has_parent_path()) std::filesystem::create_directories(out_path.parent_path());
  if (const std::filesystem::path stats_path(a.stats); stats_path.has_parent_path()) {
    std::error_code ec;  // an unwritable place fails below, with the file's name
    std::filesystem::create_directories(stats_path.parent_path(), ec);
  }

  std::unique_ptr<tbb::global_control> limit;
  if (a.threads > 0)
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  size_t(a.threads));
  ProgressBar bar;
  EmbeddedRender out = RenderOnEmbeddedFarm(a.scene, s, a.workers, [&](const v1::JobStatus& st) {
    if (!a.quiet && st.state() == v1::JOB_STATE_RUNNING)
      bar.Update(ProgressPhase(st), st.tasks_done(), st.tasks_total());
  });
  bar.Finish();
  AddClampProbe(a.scene, s, clamp_probe, &out.stats);
  // All outputs or none: a failure on a later file (an unwritable --stats) removes the earlier
  // ones, so a failed run never leaves a result that looks complete.
  const std::string png = a.out.substr(0, a.out.size() - 4) + ".png";
  try {
    WriteEXR(a.out, out.image);
    WritePNG(png, out.image);
    if (!a.stats.empty()) WriteFileAtomically(a.stats, out.stats.dump(2) + "\n");
  } catch (...) {
    std::error_code ec;
    for (const std::string& written : {a.out, png}) std::filesystem::remove(written, ec);
    throw;
  }
  if (!a.quiet) {
    std::fprintf(stderr, "%s: %s, %zu lights, %.2fs -> %s\n", a.scene.c_str(),
                 out.stats["method"].get<std::string>().c_str(),
                 out.stats["lights"]["total"].get<size_t>(),
                 out.stats["time"]["total_s"].get<double>(), a.out.c_str());
  }
  ReportTargetError(target, a.target, a.scene, s, out.image, out.stats["time"]["total_s"].get<double>());
}

}  // namespace

void AddRenderCommand(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand("render", "Render a pbrt-v4 scene on an embedded farm in this process");
  cmd->add_option("scene", args->scene, "pbrt-v4 scene file")->required()->check(CLI::ExistingFile);
  AddRenderOptions(cmd, args->render);
  AddTargetErrorOptions(cmd, args->target);
  cmd->add_option("--out", args->out, "Output EXR (a tone-mapped PNG is written beside it)");
  cmd->add_option("--stats", args->stats, "Write stats JSON here");
  cmd->add_option("--threads", args->threads, "Worker threads (0 = all cores)")
      ->check(CLI::Range(0, 4096));
  cmd->add_option("--workers", args->workers, "Workers of the embedded farm")
      ->check(CLI::Range(1, 256));
  cmd->add_flag("--quiet", args->quiet, "No progress output");
  cmd->callback([args] { RunRender(*args); });
}

}  // namespace lightfarm::cli
