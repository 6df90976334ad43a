#include "common/scene/effects.h"

namespace lightfarm {

std::vector<std::string> Effects::Names() const {
  std::vector<std::string> n;
  if (area_lights) n.push_back("area_lights");
  if (point_lights) n.push_back("point_lights");
  if (distant_lights) n.push_back("distant_lights");
  if (environment) n.push_back("environment");
  if (direct()) n.push_back("direct");
  if (indirect()) n.push_back("indirect");
  if (diffuse) n.push_back("diffuse");
  if (glossy) n.push_back("glossy");
  if (specular) n.push_back("specular");
  if (transmission) n.push_back("transmission");
  if (caustics()) n.push_back("caustics");
  if (media) n.push_back("media");
  return n;
}

Effects ComputeEffects(const Scene& scene) {
  Effects e;
  e.area_lights = !scene.area_emitters().empty();
  e.point_lights = !scene.point_emitters().empty();
  e.distant_lights = !scene.distant_emitters().empty();
  e.environment = !scene.infinite_emitters().empty();
  e.media = scene.has_media();
  e.max_depth = scene.hints().max_depth;
  // Only materials that some shape uses count.
  std::vector<bool> used(scene.materials().size(), false);
  for (const Shape& s : scene.shapes()) used[s.material] = true;
  for (size_t i = 0; i < used.size(); ++i) {
    if (!used[i]) continue;
    uint32_t f = MaterialFlags(scene.materials()[i]);
    e.diffuse |= (f & kBxDFDiffuse) != 0;
    e.glossy |= (f & kBxDFGlossy) != 0;
    e.specular |= (f & kBxDFSpecular) != 0;
    e.transmission |= (f & kBxDFTransmission) != 0;
  }
  return e;
}

}  // namespace lightfarm
