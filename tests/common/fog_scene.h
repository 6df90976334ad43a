// A homogeneous fog shared by the media element tests: σ_a 0.3, σ_s 0.9, HG g 0.4 inside an
// interface sphere of radius 20 around the origin, a camera at z = 50 looking at it, and outside
// the fog (at z = -30) a diffuse sphere of radius 1 whose ρ = 0.5 Lambertian material the tests'
// receivers use. Path depth 5 (volpath).
#pragma once

#include <memory>

#include "common/scene/scene_description.h"
#include "common/scene/scene.h"

namespace lightfarm::testing {

inline std::unique_ptr<Scene> FogScene() {
  SceneDescription desc = ParseSceneString(
      "Integrator \"volpath\" \"integer maxdepth\" [5]\n"
      "LookAt 0 0 50  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\n"
      "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.3 0.3 0.3]\n"
      "  \"rgb sigma_s\" [0.9 0.9 0.9] \"float g\" [0.4]\n"
      "AttributeBegin\nMediumInterface \"fog\" \"\"\nMaterial \"interface\"\n"
      "Shape \"sphere\" \"float radius\" [20]\nAttributeEnd\n"
      "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
      "AttributeBegin\nTranslate 0 0 -30\nShape \"sphere\" \"float radius\" [1]\nAttributeEnd\n",
      "fog.pbrt", "/tmp");
  return Scene::Build(desc, SceneBuildOptions{});
}

}  // namespace lightfarm::testing
