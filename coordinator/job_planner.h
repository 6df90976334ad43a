// The coordinator's planning I/O, kept apart from its scheduling: materializing a job's scene
// from the blob store, planning a stage (as `render` would), combining a finished stage into the
// next one's input, and assembling the result. Every call here runs on the planner pool without
// the scheduler's lock; the durable state it writes (blobs, artifacts, task rows, the result)
// is what a restarted coordinator resumes from. Coordinator (coordinator.h) owns the jobs, the
// task queue and the leases, and only moves what these calls return into them.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/farm/job_types.h"
#include "common/render/render_job.h"
#include "common/render/serialize.h"
#include "coordinator/blob_store.h"
#include "coordinator/job_images.h"
#include "coordinator/job_store.h"

namespace lightfarm {

struct PlanLimits {
  int max_resolution = 16384;  // per axis
  int max_spp = 4096;
};

// A stage ready to run: the plan it belongs to, its task specs, and the store's rows for them
// (a resumed stage keeps the attempts and results it had).
struct PlannedStage {
  std::shared_ptr<Plan> plan;
  PhaseTimes times;
  std::string lights_sha, receivers_sha, artifact_sha;
  std::vector<SubMatrixTask> specs;
  std::vector<TaskRecord> records;
};

// The stage after a combined one: its input artifact and its tasks.
struct NextStage {
  std::string artifact_sha;
  std::vector<SubMatrixTask> specs;
  std::vector<TaskRecord> records;  // a stage recomputed after a repair keeps what it had
};

// One finished render (a job, or a pass of a progressive job): its image and stats.
struct PassOutcome {
  Image image;
  nlohmann::json stats;
  uint64_t tasks = 0, attempts = 0;
};

struct FinishedJob {
  Image image;  // the result stored as result_sha (a progressive job: the mean of its passes)
  std::string result_sha, stats_json;
  uint64_t tasks = 0, attempts = 0;
  bool more_passes = false;  // a progressive job goes on with its next pass
  NoiseEstimate noise;
};

class JobPlanner {
 public:
  JobPlanner(std::string state_dir, PlanLimits limits, JobStore& store, BlobStore& blobs)
      : state_dir_(std::move(state_dir)), limits_(limits), store_(store), blobs_(blobs) {}

  // Plans job `id` and readies `stage` (its input is the previous stage's stored artifact).
  // Throws with a message for the user: scene errors name the file as submitted.
  PlannedStage PlanStage(int64_t id, const SceneManifest& manifest, const RenderSettings& settings,
                         int stage);
  // Stage `stage`'s results (task order) combined into the next stage's input, stored first so
  // that a restarted coordinator resumes from it; the next stage's task rows are created.
  NextStage CombineStage(int64_t id, const Plan& plan, int stage, const std::vector<std::string>& result_shas);
  // Every stage's outputs (the store's order) into the film and the stats.
  PassOutcome AssemblePass(int64_t id, const Plan& plan, const RenderSettings& settings,
                           const std::string& root, int final_stage, const std::vector<Bytes>& final_specs,
                           PhaseTimes times, double total_seconds);
  // An ordinary job's result: the EXR and the stats recorded, the job done, its scene removed.
  FinishedJob Finish(int64_t id, PassOutcome pass);
  // A progressive job's pass: added to `acc` (pass `pass`, in pass order), the mean of the
  // passes so far recorded as the job's result, and either the next pass readied (its tasks
  // start from stage 0) or the job done. The time limit counts the passes' own times (so a restart does not reset it).
  FinishedJob FinishPass(int64_t id, int pass, const PassPlan& passes, PassAccumulator& acc, PassOutcome outcome,
                         double pass_seconds, uint64_t job_seed, const nlohmann::json& previous_stats);
  // The preview of the finished tiles: (task spec, result blob) pairs of the final stage.
  JobPreview Preview(int64_t id, const Plan& plan, const std::vector<std::pair<Bytes, std::string>>& done);
  // The preview of a progressive job's mean so far.
  JobPreview Preview(int64_t id, Image mean, uint64_t version);

 private:
  std::string JobDir(int64_t id) const { return state_dir_ + "/jobs/" + std::to_string(id); }
  void MaterializeScene(const SceneManifest& manifest, const std::string& dir);

  std::string state_dir_;
  PlanLimits limits_;
  JobStore& store_;
  BlobStore& blobs_;
};

}  // namespace lightfarm
