// Turning a scene's emitters into the virtual light set (the matrix columns).
#pragma once

#include <cstdint>

#include "common/lights/virtual_light.h"
#include "common/scene/scene.h"

namespace lightfarm {

struct LightGenerationOptions {
  size_t target_lights = 10000;  // total virtual lights wanted (a target; see below)
  // Share of the budget spent on the emitters themselves (area lights, environment); the rest
  // goes to indirect VPLs from particle tracing. With maxdepth <= 1 everything is direct.
  float direct_fraction = 0.5f;
  int max_depth = 5;        // the scene's path depth (Integrator maxdepth)
  uint64_t seed = 0;
  // Leave a kMediumVPL at every particle scattering event in a medium (only for gather methods
  // that evaluate them; otherwise particles still scatter and attenuate in media).
  bool medium_lights = false;
};

// Deterministic for a given seed whatever the thread count: every path and every emitter sample
// draws from its own hashed generator, and paths are consumed in index order.
//
// Direct lights: area emitters get VPLs by stratified sampling ∝ emitted power; infinite lights
// become directional lights by importance sampling the map; point, spot and distant lights are
// one column each. Indirect: particle paths leave a VPL at every non-specular surface vertex up
// to maxdepth - 1 bounces (paths through specular vertices carry caustics; glossy VPLs keep their
// arrival direction), with Russian roulette. Paths are traced until the indirect budget is met;
// every VPL's power is divided by the number of paths started.
LightSet GenerateLights(const Scene& scene, const LightGenerationOptions& opt);

}  // namespace lightfarm
