// `lightfarm submit SCENE --server HOST:PORT [render options] [--wait] [--out FILE.exr]`:
// uploads the scene files the coordinator lacks, submits a job, prints its id; with --wait,
// follows it (progress bar, ETA) and fetches the result.
#include <iostream>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/farm_options.h"
#include "cli/progress.h"
#include "cli/render_options.h"
#include "cli/target_error.h"
#include "common/image/image_io.h"
#include "common/farm/proto_convert.h"

namespace lightfarm::cli {

namespace {

struct SubmitArgs {
  std::string scene;
  RenderOptionArgs render;
  TargetErrorArgs target;
  ServerArgs server;
  int priority = 0;
  std::string name;
  bool wait = false;
  std::string out, stats;
  bool quiet = false;
  bool verify = false;
};

void RunSubmit(const SubmitArgs& a) {
  RenderSettings settings = ToRenderSettings(a.render);
  settings.verify = a.verify;
  TargetErrorArgs target_args = a.target;
  target_args.lights_given = a.render.lights > 0;
  const TargetErrorPlan target = ApplyTargetError(target_args, a.scene, &settings);
  if (!a.out.empty() && !a.wait) throw OptionError("--out needs --wait (or use `lightfarm fetch` later)");
  auto client = ConnectToCoordinator(a.server);
  // A scene that does not parse here is still submitted: the coordinator fails the job and
  // reports file:line, like any render error.
  v1::SceneManifest manifest = client->UploadScene(a.scene, /*strict=*/false);
  const std::string job = client->Submit(manifest, settings, a.priority, a.name.empty() ? a.scene : a.name);
  std::cout << job << std::endl;
  if (!a.wait) return;
  ProgressBar bar;
  v1::JobStatus st = client->Watch(job, [&](const v1::JobStatus& s) {
    if (!a.quiet && s.state() == v1::JOB_STATE_RUNNING) bar.Update(ProgressPhase(s), s.tasks_done(), s.tasks_total());
  });
  bar.Finish();
  if (st.state() != v1::JOB_STATE_DONE) throw std::runtime_error(DescribeJob(st));
  if (!a.out.empty()) {
    std::string exr, stats;
    client->Fetch(job, &exr, &stats);
    WriteFetchedResult(a.out, exr, stats, a.stats);
    if (target.active) {
      const auto job_stats = nlohmann::json::parse(stats, nullptr, false);
      const double seconds = job_stats.is_object() && job_stats.contains("time")
                                 ? job_stats["time"].value("total_s", 0.0) : 0.0;
      ReportTargetError(target, a.target, a.scene, settings, ReadImage(a.out), seconds);
    }
  }
  if (!a.quiet) std::cerr << DescribeJob(st) << "\n";
}

}  // namespace

void AddSubmitCommand(CLI::App& app) {
  auto args = std::make_shared<SubmitArgs>();
  CLI::App* cmd = app.add_subcommand("submit", "Submit a scene to a render farm");
  cmd->add_option("scene", args->scene, "pbrt-v4 scene file")->required()->check(CLI::ExistingFile);
  AddRenderOptions(cmd, args->render);
  AddTargetErrorOptions(cmd, args->target);
  AddServerOptions(cmd, args->server);
  cmd->add_option("--priority", args->priority, "Higher runs first");
  cmd->add_option("--name", args->name, "Job label (default: the scene path)");
  cmd->add_flag("--wait", args->wait, "Wait for the job to finish");
  cmd->add_option("--out", args->out, "With --wait: write the result EXR (+ PNG, stats JSON)");
  cmd->add_option("--stats", args->stats, "Stats JSON path (default: beside --out)");
  cmd->add_flag("--quiet", args->quiet, "No progress output");
  cmd->add_flag("--verify", args->verify,
                "Run every task on two workers and compare their results bit for bit (a third decides)");
  cmd->callback([args] { RunSubmit(*args); });
}

}  // namespace lightfarm::cli
