// Conversion between the protocol's messages (proto/lightfarm/v1) and the core types. Includes
// only generated protobuf messages, never gRPC; built into lightfarm_farm, not lightfarm_common.
#pragma once

#include "common/render/render_job.h"
#include "lightfarm/v1/types.pb.h"

namespace lightfarm {

v1::RenderSettings ToProto(const RenderSettings& s);
RenderSettings FromProto(const v1::RenderSettings& p);

const char* JobStateName(v1::JobState state);  // "queued", "running", ...
bool IsTerminal(v1::JobState state);

}  // namespace lightfarm
