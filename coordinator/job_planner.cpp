#include "coordinator/job_planner.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "common/farm/proto_convert.h"
#include "common/render/stage_engine.h"
#include "common/scene/scene_cache.h"
#include "common/util/error.h"

namespace lightfarm {

namespace fs = std::filesystem;

namespace {

std::string ReplaceAll(std::string s, const std::string& from, const std::string& to) {
  if (from.empty()) return s;
  for (size_t pos = 0; (pos = s.find(from, pos)) != std::string::npos; pos += to.size())
    s.replace(pos, from.size(), to);
  return s;
}

double SecondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

void JobPlanner::MaterializeScene(const SceneManifest& manifest, const std::string& dir) {
  std::error_code ec;
  fs::remove_all(dir, ec);
  for (const SceneFileRef& f : manifest.files) {
    const fs::path target = fs::path(dir) / f.path;
    fs::create_directories(target.parent_path());
    // Only a file that still hashes to what was uploaded is parsed (a corrupted one is quarantined).
    blobs_.CheckIntact(f.sha256);
    fs::copy_file(blobs_.Path(f.sha256), target, fs::copy_options::overwrite_existing);
  }
}

PlannedStage JobPlanner::PlanStage(int64_t id, const SceneManifest& manifest, const RenderSettings& settings,
                                   int stage) {
  const std::string dir = JobDir(id) + "/scene";
  MaterializeScene(manifest, dir);
  PlannedStage out;
  try {
    // Parsed once per job (and once per embedded process: the client's parse), each pass after
    // the first from the cache.
    const std::shared_ptr<const SceneDescription> desc =
        SceneCache::Process().Get(manifest.ContentKey(), dir, manifest.root);
    out.plan = std::make_shared<Plan>(BuildPlan(*desc, settings, &out.times));
  } catch (const SceneError& e) {
    // Name the file as the user knows it: relative to the scene's directory.
    throw std::runtime_error(ReplaceAll(e.what(), dir + "/", ""));
  }
  const ReceiverSet& receivers = *out.plan->receivers;
  if (receivers.width > limits_.max_resolution || receivers.height > limits_.max_resolution)
    throw std::runtime_error("the scene's resolution " + std::to_string(receivers.width) + "x" +
                             std::to_string(receivers.height) + " exceeds the limit of " +
                             std::to_string(limits_.max_resolution) + " per axis");
  if (receivers.spp > limits_.max_spp)
    throw std::runtime_error("the method's default of " + std::to_string(receivers.spp) +
                             " samples per pixel exceeds the limit of " + std::to_string(limits_.max_spp) +
                             " (set spp)");
  out.lights_sha = blobs_.Put(SerializeLightSet(*out.plan->lights));
  out.receivers_sha = blobs_.Put(SerializeReceiverSet(receivers));
  // The stage to (re)start: its input artifact is the previous stage's.
  StageArtifact artifact;
  if (stage > 0) {
    const auto artifacts = store_.Artifacts(id);
    if (!artifacts.count(stage - 1))
      throw std::runtime_error("artifact of stage " + std::to_string(stage - 1) + " is missing");
    out.artifact_sha = artifacts.at(stage - 1);
    artifact = blobs_.Get(out.artifact_sha);
  }
  out.specs = StageEngine(*out.plan).Tasks(stage, artifact);
  store_.InsertTasks(id, stage, int(out.specs.size()));
  out.records = store_.LoadTasks(id, stage);
  return out;
}

NextStage JobPlanner::CombineStage(int64_t id, const Plan& plan, int stage,
                                   const std::vector<std::string>& result_shas) {
  const StageEngine engine(plan);
  std::vector<TaskOutput> outputs;
  outputs.reserve(result_shas.size());
  for (const std::string& sha : result_shas) outputs.push_back(DeserializeTaskOutput(blobs_.Get(sha)));
  const StageArtifact artifact = engine.Combine(stage, outputs);
  NextStage next;
  next.artifact_sha = blobs_.Put(artifact);
  store_.SetArtifact(id, stage, next.artifact_sha);
  next.specs = engine.Tasks(stage + 1, artifact);
  store_.InsertTasks(id, stage + 1, int(next.specs.size()));
  store_.SetJobStage(id, stage + 1);
  next.records = store_.LoadTasks(id, stage + 1);
  return next;
}

PassOutcome JobPlanner::AssemblePass(int64_t id, const Plan& plan, const RenderSettings& settings,
                                     const std::string& root, int final_stage,
                                     const std::vector<Bytes>& final_specs, PhaseTimes times,
                                     double total_seconds) {
  const auto t_film = std::chrono::steady_clock::now();
  // Every stage's outputs in (stage, task) order (the store's), as the stage engine requires.
  StageEngine engine(plan);
  PassOutcome out;
  for (const TaskRecord& r : store_.LoadAllTasks(id)) {
    out.attempts += uint64_t(r.attempts);
    ++out.tasks;
    if (r.state != int(TaskStateCode::kDone))
      throw std::runtime_error("task " + std::to_string(r.task_id) + " has no result");
    const TaskOutput task_output = DeserializeTaskOutput(blobs_.Get(r.result_sha));
    engine.Count(task_output);
    if (r.stage == final_stage)
      engine.AddFinal(DeserializeTask(final_specs.at(size_t(r.task_id))), task_output);
  }
  uint64_t nan_samples = 0;
  out.image = AssembleImage(plan, engine.outcome(), &nan_samples);
  times.Add("film", SecondsSince(t_film));
  out.stats = MakeStats(plan, settings, engine.outcome(), nan_samples, times,
                        total_seconds + SecondsSince(t_film));
  out.stats["scene"] = root;
  out.stats["farm"] = {{"job_id", std::to_string(id)}, {"attempts", out.attempts}, {"tasks", out.tasks}};
  return out;
}

FinishedJob JobPlanner::Finish(int64_t id, PassOutcome pass) {
  FinishedJob out;
  out.tasks = pass.tasks;
  out.attempts = pass.attempts;
  out.result_sha = blobs_.Put(WriteResultExr(pass.image, JobDir(id) + "/result.exr"));
  out.image = std::move(pass.image);
  out.stats_json = pass.stats.dump(2);
  store_.FinishJob(id, JobState::kDone, out.result_sha, out.stats_json);
  std::error_code ec;
  fs::remove_all(JobDir(id) + "/scene", ec);
  return out;
}

namespace {

// JSON has no infinity: an estimate not yet made (fewer than two passes) is null.
nlohmann::json Finite(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

}  // namespace

FinishedJob JobPlanner::FinishPass(int64_t id, int pass, const PassPlan& passes, PassAccumulator& acc,
                                   PassOutcome outcome, double pass_seconds, uint64_t job_seed,
                                   const nlohmann::json& previous_stats) {
  if (int(acc.passes()) != pass)
    throw std::runtime_error("pass " + std::to_string(pass) + " finished with " + std::to_string(acc.passes()) +
                             " passes accumulated");
  acc.Add(outcome.image, pass_seconds);
  double elapsed = 0;
  for (double t : acc.pass_seconds()) elapsed += t;
  FinishedJob out;
  out.more_passes = WantsAnotherPass(passes, acc, elapsed);
  out.noise = acc.Noise();
  // The farm's totals are over every pass: the earlier ones are in the previous result's stats.
  out.tasks = outcome.tasks;
  out.attempts = outcome.attempts;
  if (previous_stats.contains("farm")) {
    out.tasks += previous_stats["farm"].value("tasks", uint64_t(0));
    out.attempts += previous_stats["farm"].value("attempts", uint64_t(0));
  }
  nlohmann::json stats = std::move(outcome.stats);
  stats["farm"]["tasks"] = out.tasks;
  stats["farm"]["attempts"] = out.attempts;
  stats["seed"] = job_seed;  // MakeStats wrote the pass's seed
  stats["passes"] = acc.passes();
  stats["noise"] = {{"rel_stderr", Finite(out.noise.rel_stderr)},
                    {"p90_rel_stderr", Finite(out.noise.p90_rel_stderr)}};
  stats["pass_times_s"] = acc.pass_seconds();
  stats["progressive"] = {{"max_passes", passes.passes},
                          {"until_noise", passes.until_noise},
                          {"time_limit_s", passes.time_limit_s},
                          {"elapsed_s", elapsed},
                          {"finished", !out.more_passes}};
  stats["time"]["total_s"] = elapsed;
  out.stats_json = stats.dump(2);
  out.image = acc.Mean();
  out.result_sha = blobs_.Put(WriteResultExr(out.image, JobDir(id) + "/result.exr"));
  const std::string accum_sha = blobs_.Put(acc.Serialize());
  // The finished pass, its accumulation and the result are recorded in one step before the next
  // pass starts: a restarted coordinator resumes at the next pass with every finished one.
  store_.FinishPass(id, pass + 1, accum_sha, out.result_sha, out.stats_json);
  if (!out.more_passes) {
    store_.FinishJob(id, JobState::kDone, out.result_sha, out.stats_json);
    std::error_code ec;
    fs::remove_all(JobDir(id) + "/scene", ec);
  }
  return out;
}

JobPreview JobPlanner::Preview(int64_t id, const Plan& plan,
                               const std::vector<std::pair<Bytes, std::string>>& done) {
  std::vector<std::pair<SubMatrixTask, TaskOutput>> tiles;
  tiles.reserve(done.size());
  for (const auto& [spec, sha] : done) tiles.emplace_back(DeserializeTask(spec), DeserializeTaskOutput(blobs_.Get(sha)));
  return MakePreview(plan, tiles, JobDir(id) + "/preview.png");
}

JobPreview JobPlanner::Preview(int64_t id, Image mean, uint64_t version) {
  return MakePreview(std::move(mean), version, JobDir(id) + "/preview.png");
}

}  // namespace lightfarm
