#include "common/scene/camera.h"

#include <cmath>

#include "common/util/sampling.h"

namespace lightfarm {

Camera Camera::Create(const CameraDesc& desc, int width, int height) {
  Camera cam;
  const ParamSet& ps = desc.params;
  if (desc.type == "perspective") {
    cam.type_ = Type::kPerspective;
  } else if (desc.type == "orthographic") {
    cam.type_ = Type::kOrthographic;
  } else {
    throw SceneError(desc.loc, "unsupported camera type \"" + desc.type +
                                   "\" (supported: perspective, orthographic)");
  }
  auto inv = desc.camera_from_world.Inverse();
  if (!inv) throw SceneError(desc.loc, "camera transform is singular");
  cam.world_from_camera_ = *inv;
  cam.camera_from_world_ = desc.camera_from_world;

  // Screen window: the shorter image axis spans [-1, 1] (pbrt-v4 CameraBase).
  float aspect = ps.GetOneFloat("frameaspectratio", float(width) / float(height));
  float sw[4];
  if (aspect > 1.f) {
    sw[0] = -aspect; sw[1] = aspect; sw[2] = -1.f; sw[3] = 1.f;
  } else {
    sw[0] = -1.f; sw[1] = 1.f; sw[2] = -1.f / aspect; sw[3] = 1.f / aspect;
  }
  std::vector<float> user_sw = ps.GetFloatArray("screenwindow");
  if (!user_sw.empty()) {
    if (user_sw.size() != 4) throw SceneError(desc.loc, "\"screenwindow\" needs 4 values");
    for (int i = 0; i < 4; ++i) sw[i] = user_sw[i];
  }
  cam.lens_radius_ = ps.GetOneFloat("lensradius", 0.f);
  cam.focal_distance_ = ps.GetOneFloat("focaldistance", 1e6f);
  if (cam.lens_radius_ < 0.f) throw SceneError(desc.loc, "\"lensradius\" must be >= 0");
  if (cam.focal_distance_ <= 0.f) throw SceneError(desc.loc, "\"focaldistance\" must be > 0");
  float shutteropen = ps.GetOneFloat("shutteropen", 0.f);
  float shutterclose = ps.GetOneFloat("shutterclose", 1.f);
  (void)shutteropen;
  (void)shutterclose;  // no motion blur: the shutter interval does not change a static image

  Transform screen_from_camera;
  if (cam.type_ == Type::kPerspective) {
    float fov = ps.GetOneFloat("fov", 90.f);
    if (!(fov > 0.f && fov < 180.f)) throw SceneError(desc.loc, "\"fov\" must be in (0, 180)");
    screen_from_camera = Transform::Perspective(fov, 1e-2f, 1000.f);
  } else {
    // Orthographic: z maps [near, far] to [0, 1]; x, y unchanged.
    screen_from_camera = Transform::Scale(1, 1, 1.f / (1000.f)) * Transform::Translate({0, 0, 0});
  }
  Transform ndc_from_screen =
      Transform::Scale(1.f / (sw[1] - sw[0]), 1.f / (sw[2] - sw[3]), 1) *
      Transform::Translate({-sw[0], -sw[3], 0});
  Transform raster_from_ndc = Transform::Scale(float(width), float(height), 1);
  Transform raster_from_camera = raster_from_ndc * ndc_from_screen * screen_from_camera;
  auto camera_from_raster = raster_from_camera.Inverse();
  if (!camera_from_raster) throw SceneError(desc.loc, "camera projection is singular");
  cam.camera_from_raster_ = *camera_from_raster;
  cam.raster_from_camera_ = raster_from_camera;
  ps.ReportUnused("Camera \"" + desc.type + "\"");
  return cam;
}

std::optional<std::pair<Vec2, Vec2>> Camera::ImageBounds(Vec3 p_world) const {
  const Vec3 p = camera_from_world_.ApplyPoint(p_world);
  // The perspective projection divides by z: only points in front of the eye have an image.
  if (type_ == Type::kPerspective && !(p.z > 1e-6f)) return std::nullopt;
  // The film position whose ray from lens point l passes through p (GenerateRay's thin lens
  // inverted): perspective, the pinhole image of where the line from l through p meets the plane
  // of focus; orthographic, the film point moved by -l (1 - z / focal distance). The map is
  // affine in l, so the lens disk's image is a disk and its four axis points bound it.
  auto image = [&](Vec2 l) -> std::optional<Vec2> {
    Vec3 p_film_camera;
    if (type_ == Type::kPerspective) {
      const Vec3 o{l.x, l.y, 0};
      p_film_camera = o + (p - o) * (focal_distance_ / p.z);
    } else {
      const float k = 1.f - p.z / focal_distance_;
      p_film_camera = {p.x - l.x * k, p.y - l.y * k, 0};
    }
    const Vec3 r = raster_from_camera_.ApplyPoint(p_film_camera);
    if (!std::isfinite(r.x) || !std::isfinite(r.y)) return std::nullopt;
    return Vec2{r.x, r.y};
  };
  Vec2 lo{kInfinity, kInfinity}, hi{-kInfinity, -kInfinity};
  const float R = lens_radius_;
  const Vec2 lens_points[4] = {{R, 0}, {-R, 0}, {0, R}, {0, -R}};
  for (int i = 0; i < (R > 0.f ? 4 : 1); ++i) {
    const std::optional<Vec2> q = image(R > 0.f ? lens_points[i] : Vec2{0, 0});
    if (!q) return std::nullopt;
    lo = {std::min(lo.x, q->x), std::min(lo.y, q->y)};
    hi = {std::max(hi.x, q->x), std::max(hi.y, q->y)};
  }
  return std::pair{lo, hi};
}

Ray Camera::GenerateRay(Vec2 p_film, Vec2 u_lens) const {
  Vec3 p_camera = camera_from_raster_.ApplyPoint({p_film.x, p_film.y, 0});
  Ray ray;
  if (type_ == Type::kPerspective) {
    ray.o = {0, 0, 0};
    ray.d = Normalize(p_camera);
  } else {
    ray.o = p_camera;
    ray.d = {0, 0, 1};
  }
  if (lens_radius_ > 0.f) {
    // Thin lens: move the origin on the lens, aim at the point on the plane of focus.
    Vec2 p_lens = SampleUniformDiskConcentric(u_lens) * lens_radius_;
    float ft = focal_distance_ / ray.d.z;
    Vec3 p_focus = ray.o + ray.d * ft;
    ray.o = {ray.o.x + p_lens.x, ray.o.y + p_lens.y, ray.o.z};
    ray.d = Normalize(p_focus - ray.o);
  }
  ray.o = world_from_camera_.ApplyPoint(ray.o);
  ray.d = Normalize(world_from_camera_.ApplyVector(ray.d));
  return ray;
}

}  // namespace lightfarm
