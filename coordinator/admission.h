// What the coordinator admits: a job request checked before it is queued, so that nothing a
// client sends can fail later for a reason known now. The manifest must list every file once,
// at a relative path without "..", with a SHA-256 the blob store holds, the root among them; the
// settings must be well formed (INVALID_ARGUMENT) and within the farm's limits
// (RESOURCE_EXHAUSTED), and the method and its parameters must be ones the renderer accepts.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "common/farm/job_types.h"
#include "common/render/render_job.h"
#include "coordinator/farm_error.h"

namespace lightfarm {

struct AdmissionLimits {
  int max_resolution = 16384;  // per axis
  uint64_t max_lights = 50'000'000;
  int max_spp = 4096;
};

// A job as a client submits it, in the scheduler's plain types (the gRPC service converts the
// wire's SubmitJobRequest).
struct JobRequest {
  std::string name;
  int priority = 0;
  SceneManifest manifest;
  RenderSettings settings;
};

// Throws FarmError naming what is wrong; `stored(sha)` says whether the blob store has a file.
void CheckSubmission(const JobRequest& request, const AdmissionLimits& limits,
                     const std::function<bool(const std::string& sha256)>& stored);

}  // namespace lightfarm
