// pbrt-v4 cameras: perspective (with thin lens) and orthographic. Raster space has x to the
// right and y down, (0,0) at the top-left corner of the film; screen space spans the screen
// window with y up; the camera looks down +z (pbrt's left-handed camera space).
#pragma once

#include <optional>
#include <string>
#include <utility>

#include "common/scene/scene_description.h"
#include "common/util/math.h"
#include "common/util/transform.h"

namespace lightfarm {

struct Ray {
  Vec3 o, d;
  float tmax = kInfinity;
};

class Camera {
 public:
  enum class Type { kPerspective, kOrthographic };
  // Reads the Camera directive's parameters for a film of the given resolution.
  static Camera Create(const CameraDesc& desc, int width, int height);

  // Ray through raster position p_film (continuous pixel coordinates) and lens sample u_lens.
  Ray GenerateRay(Vec2 p_film, Vec2 u_lens) const;

  // Raster bounds (lower, upper corner) of the image of a world point in front of the camera: a
  // single position through a pinhole, the disk of confusion through a thin lens (lensradius >
  // 0); nullopt for a point behind the camera.
  std::optional<std::pair<Vec2, Vec2>> ImageBounds(Vec3 p_world) const;

  Vec3 position() const { return world_from_camera_.ApplyPoint({0, 0, 0}); }
  Type type() const { return type_; }

 private:
  Type type_ = Type::kPerspective;
  Transform world_from_camera_;
  Transform camera_from_raster_;
  Transform camera_from_world_, raster_from_camera_;
  float lens_radius_ = 0, focal_distance_ = 1e6f;
};

}  // namespace lightfarm
