// What a scene calls for, computed before planning so that the plan creates only what is needed
// (DESIGN.md, "Simulate only the effects a scene calls for").
#pragma once

#include <string>
#include <vector>

#include "common/scene/scene.h"

namespace lightfarm {

struct Effects {
  bool area_lights = false, point_lights = false, distant_lights = false, environment = false;
  bool diffuse = false, glossy = false, specular = false, transmission = false;
  bool media = false;
  int max_depth = 0;
  bool direct() const { return max_depth >= 1; }
  bool indirect() const { return max_depth >= 2; }
  // Caustic paths: light through a specular interaction onto a non-specular surface.
  bool caustics() const { return specular && indirect(); }
  // Stable names for the stats JSON "effects" list.
  std::vector<std::string> Names() const;
};

Effects ComputeEffects(const Scene& scene);

}  // namespace lightfarm
