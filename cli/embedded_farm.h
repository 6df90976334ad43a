// Embedded mode (`lightfarm render`): a coordinator and N workers in this process, talking over
// in-process gRPC channels: the same code path as the farm, without sockets. The farm stores its
// result as always; the caller gets the film's float image in process (no EXR decode) and the
// stats from the coordinator.
#pragma once

#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "common/render/render_job.h"
#include "lightfarm/v1/render.pb.h"

namespace lightfarm {

struct EmbeddedRender {
  Image image;
  nlohmann::json stats;
};

// Throws SceneError for a scene that does not parse (naming file:line), OptionError for invalid
// settings, std::runtime_error when the job fails.
EmbeddedRender RenderOnEmbeddedFarm(const std::string& scene_path, const RenderSettings& settings,
                                    int workers,
                                    const std::function<void(const v1::JobStatus&)>& progress = nullptr);

}  // namespace lightfarm
