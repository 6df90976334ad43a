// Conversion between the protocol's messages (proto/lightfarm/v1) and the core types. Includes
// only generated protobuf messages, never gRPC; built into lightfarm_farm, not lightfarm_common.
#pragma once

#include <string>

#include "common/farm/job_types.h"
#include "common/render/render_job.h"
#include "lightfarm/v1/types.pb.h"

namespace lightfarm {

v1::RenderSettings ToProto(const RenderSettings& s);
RenderSettings FromProto(const v1::RenderSettings& p);

v1::JobState ToProto(JobState state);
JobState FromProto(v1::JobState state);  // UNSPECIFIED (no job has it) reads as queued
v1::SceneManifest ToProto(const SceneManifest& m);
SceneManifest FromProto(const v1::SceneManifest& m);

// The coordinator's store keeps a job's manifest and settings in the wire's encoding (a store
// written by an older coordinator reads the same).
std::string EncodeManifest(const SceneManifest& m);
SceneManifest DecodeManifest(const std::string& bytes);
std::string EncodeSettings(const RenderSettings& s);
RenderSettings DecodeSettings(const std::string& bytes);

const char* JobStateName(v1::JobState state);  // "queued", "running", ...
bool IsTerminal(v1::JobState state);

}  // namespace lightfarm
