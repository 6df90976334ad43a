// What the coordinator reports of a job and of a worker, in plain types: the gRPC service
// (services.cpp) puts them on the wire as v1::JobStatus and v1::WorkerStatus, the dashboard
// (dashboard.cpp) as JSON. The scheduler never builds a protocol message itself.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/farm/job_types.h"

namespace lightfarm {

struct JobSnapshot {
  std::string job_id;
  JobState state = JobState::kQueued;
  std::string name;
  int priority = 0;
  std::string method;
  int stage = 0, stage_count = 1;
  std::string stage_name;
  uint64_t tasks_done = 0, tasks_total = 0;  // of the current stage
  double elapsed_s = 0;
  double eta_s = -1;  // -1: unknown
  std::string error;  // valid UTF-8
  uint64_t attempts = 0, tasks_completed_total = 0, tasks_verified = 0;
  std::string scene, scene_sha256;  // the root file as the manifest names it, and its hash
  std::string waiting;              // why a job with work to do makes no progress ("" when it does)
  // Progressive jobs.
  bool progressive = false;
  uint32_t passes_done = 0, passes_total = 0;
  double noise_rel_stderr = -1, noise_p90_rel_stderr = -1;  // -1: not estimated yet
};

struct WorkerSnapshot {
  std::string worker_id, name, version;
  int threads = 0;
  std::string lease_id, job_id;  // the lease it holds, while the task is still its own
  double last_seen_s = -1;
  bool alive = false;  // seen within two lease timeouts
  uint64_t tasks_done = 0, tasks_failed = 0;
  std::vector<std::string> blocked_jobs;  // jobs it failed max-attempts tasks of
  std::string blocklisted;                // why it may run nothing here ("" when trusted)
};

}  // namespace lightfarm
