#include "common/scene/scene.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>

#include "common/image/image_io.h"
#include "common/scene/ply.h"
#include "common/util/sampling.h"

namespace lightfarm {

class SceneBuilder {
 public:
  SceneBuilder(const SceneDescription& desc, const SceneBuildOptions& opt, Scene* scene)
      : desc_(desc), opt_(opt), s_(*scene) {}

  void Build() {
    ReadHints();
    for (const auto& [name, md] : desc_.media) {
      medium_index_[name] = int(s_.media_.size());
      s_.media_.push_back(CreateMedium(md, desc_));
    }
    s_.camera_ = Camera::Create(desc_.camera, s_.hints_.width, s_.hints_.height);
    s_.camera_medium_ = MediumIndex(desc_.camera.medium, desc_.camera.loc);
    s_.has_media_ = s_.camera_medium_ >= 0;
    for (const MaterialDesc& md : desc_.materials) s_.materials_.push_back(CreateMaterial(md));
    for (const ShapeDesc& sd : desc_.shapes) AddShape(sd, sd.world_from_object);
    for (const InstanceUse& use : desc_.instance_uses) {
      auto it = desc_.instance_definitions.find(use.name);
      if (it == desc_.instance_definitions.end())
        throw SceneError(use.loc, "unknown object instance \"" + use.name + "\"");
      for (const ShapeDesc& sd : it->second) AddShape(sd, use.world_from_instance * sd.world_from_object);
    }
    for (const LightDesc& ld : desc_.lights) AddLight(ld);
    BuildEmbree();
  }

 private:
  void ReadHints() {
    RenderHints& h = s_.hints_;
    // Integrator, Sampler and Accelerator are rendering hints: read what they imply, ignore
    // the rest (their other parameters describe a path tracer's strategy, not the image).
    h.max_depth = desc_.integrator.params.GetOneInt("maxdepth", 5);
    if (h.max_depth < 0) throw SceneError(desc_.integrator.loc, "\"maxdepth\" must be >= 0");
    h.pixel_samples = desc_.sampler.params.GetOneInt("pixelsamples", 16);

    const ParamSet& film = desc_.film.params;
    if (!desc_.film.type.empty() && desc_.film.type != "rgb")
      throw SceneError(desc_.film.loc, "unsupported film type \"" + desc_.film.type +
                                           "\" (supported: rgb)");
    h.width = film.GetOneInt("xresolution", 1280);
    h.height = film.GetOneInt("yresolution", 720);
    film.GetOneString("filename", "");
    std::vector<float> crop = film.GetFloatArray("cropwindow");
    if (!crop.empty() && !(crop.size() == 4 && crop[0] == 0 && crop[1] == 1 && crop[2] == 0 &&
                           crop[3] == 1))
      throw SceneError(desc_.film.loc, "Film \"cropwindow\" is not supported");
    if (film.Has("pixelbounds"))
      throw SceneError(film.Find("pixelbounds")->loc, "Film \"pixelbounds\" is not supported");
    film.GetOneFloat("diagonal", 35.f);  // only affects realistic cameras
    if (film.GetOneFloat("iso", 100.f) != 100.f || film.GetOneFloat("exposuretime", 1.f) != 1.f)
      throw SceneError(desc_.film.loc, "Film \"iso\"/\"exposuretime\" other than 100/1 are not supported");
    std::string sensor = film.GetOneString("sensor", "cie1931");
    if (sensor != "cie1931")
      throw SceneError(desc_.film.loc, "Film \"sensor\" \"" + sensor + "\" is not supported");
    film.GetOneBool("savefp16", true);
    film.ReportUnused("Film \"rgb\"");
    if (opt_.width > 0) h.width = opt_.width;
    if (opt_.height > 0) h.height = opt_.height;
    if (h.width <= 0 || h.height <= 0 || h.width > 65536 || h.height > 65536)
      throw SceneError(desc_.film.loc, "film resolution " + std::to_string(h.width) + "x" +
                                           std::to_string(h.height) + " is out of range");

    TypedEntity f = desc_.filter;
    if (!opt_.filter.empty()) {
      f.type = opt_.filter;
      f.params = ParamSet();
      f.loc = FileLoc{"--filter", 0, 0};
    }
    h.filter_type = f.type.empty() ? "gaussian" : f.type;
    float default_radius = 0.5f;
    if (h.filter_type == "gaussian") default_radius = 1.5f;
    else if (h.filter_type == "triangle" || h.filter_type == "mitchell") default_radius = 2.f;
    else if (h.filter_type == "sinc") default_radius = 4.f;
    else if (h.filter_type != "box")
      throw SceneError(f.loc, "unsupported pixel filter \"" + h.filter_type +
                                  "\" (supported: box, triangle, gaussian, mitchell, sinc)");
    h.filter_xradius = f.params.GetOneFloat("xradius", default_radius);
    h.filter_yradius = f.params.GetOneFloat("yradius", default_radius);
    if (!(h.filter_xradius > 0 && h.filter_yradius > 0 && h.filter_xradius <= 16 &&
          h.filter_yradius <= 16))
      throw SceneError(f.loc, "pixel filter radius must be in (0, 16]");
    if (h.filter_type == "gaussian") h.filter_sigma = f.params.GetOneFloat("sigma", 0.5f);
    if (h.filter_type == "mitchell") {
      h.filter_B = f.params.GetOneFloat("B", 1.f / 3.f);
      h.filter_C = f.params.GetOneFloat("C", 1.f / 3.f);
    }
    if (h.filter_type == "sinc") h.filter_tau = f.params.GetOneFloat("tau", 3.f);
    if (!f.type.empty()) f.params.ReportUnused("PixelFilter \"" + f.type + "\"");
  }

  // Index of a named medium, -1 for "" (vacuum).
  int MediumIndex(const std::string& name, const FileLoc& loc) {
    if (name.empty()) return -1;
    auto it = medium_index_.find(name);
    if (it == medium_index_.end()) throw SceneError(loc, "unknown medium \"" + name + "\"");
    return it->second;
  }

  int MaterialIndex(const ShapeDesc& sd) {
    if (sd.material >= 0) return sd.material;
    // No material set: pbrt-v4's default is diffuse with reflectance 0.5.
    if (default_material_ < 0) {
      Material m;
      m.type = MaterialType::kDiffuse;
      m.reflectance = RGB(0.5f);
      m.name = "default diffuse";
      default_material_ = int(s_.materials_.size());
      s_.materials_.push_back(m);
    }
    return default_material_;
  }

  void AddShape(const ShapeDesc& sd, const Transform& world_from_object) {
    ShapeDesc d = sd;
    d.world_from_object = world_from_object;
    Shape shape;
    shape.inside_medium = MediumIndex(sd.inside_medium, sd.loc);
    shape.outside_medium = MediumIndex(sd.outside_medium, sd.loc);
    shape.medium_transition = shape.inside_medium != shape.outside_medium;
    if (shape.inside_medium >= 0 || shape.outside_medium >= 0) s_.has_media_ = true;
    shape.name = "Shape \"" + sd.type + "\" (" + sd.loc.ToString() + ")";
    shape.material = MaterialIndex(sd);
    shape.flip_normals = sd.reverse_orientation != world_from_object.SwapsHandedness();
    const ParamSet& ps = sd.params;
    if (ps.Has("alpha")) {
      const Param* a = ps.Find("alpha");
      if (a->type != "float" || (a->numbers.size() == 1 && a->numbers[0] != 1.0))
        throw SceneError(a->loc, "alpha cut-outs are not supported");
      ps.GetOneFloat("alpha", 1.f);
    }
    if (sd.type == "trianglemesh") {
      std::vector<Vec3> p = ps.GetPoint3Array("P");
      std::vector<int> idx = ps.GetIntArray("indices");
      if (idx.empty() && p.size() == 3) idx = {0, 1, 2};
      if (p.empty() || idx.empty())
        throw SceneError(sd.loc, "Shape \"trianglemesh\" needs \"point3 P\" and \"integer indices\"");
      std::vector<Vec3> n = ps.GetNormalArray("N");
      std::vector<Vec2> uv = ps.GetPoint2Array("uv");
      ps.GetFloatArray("S");  // tangents: only orient anisotropic lobes; not used
      ps.GetIntArray("faceIndices");
      SetMesh(&shape, d, std::move(p), std::move(n), std::move(uv), idx);
    } else if (sd.type == "plymesh") {
      std::string file = desc_.ResolvePath(ps.GetOneString("filename", ""));
      if (ps.Has("displacement"))
        throw SceneError(ps.Find("displacement")->loc, "plymesh displacement is not supported");
      ps.GetOneFloat("edgelength", 1.f);
      PlyMesh mesh;
      try {
        mesh = ReadPly(file);
      } catch (const SceneError& e) {
        // The PLY error names the mesh file; the user also needs the directive that loads it.
        throw SceneError(sd.loc, "Shape \"plymesh\": " + std::string(e.what()));
      }
      SetMesh(&shape, d, std::move(mesh.positions), std::move(mesh.normals), std::move(mesh.uvs),
              mesh.indices);
    } else if (sd.type == "sphere") {
      float radius = ps.GetOneFloat("radius", 1.f);
      float zmin = ps.GetOneFloat("zmin", -radius), zmax = ps.GetOneFloat("zmax", radius);
      float phimax = ps.GetOneFloat("phimax", 360.f);
      if (!(radius > 0) || !std::isfinite(radius))
        throw SceneError(sd.loc, "Shape \"sphere\": radius must be positive and finite");
      auto uniform = world_from_object.UniformScale();
      bool full = zmin <= -radius && zmax >= radius && phimax >= 360.f;
      if (uniform && full) {
        shape.kind = ShapeKind::kSphere;
        shape.center = world_from_object.ApplyPoint({0, 0, 0});
        shape.radius = radius * *uniform;
        if (!IsFinite(shape.center)) throw SceneError(sd.loc, "Shape \"sphere\": center not finite");
        if (!std::isfinite(4.f * kPi * shape.radius * shape.radius))
          throw SceneError(sd.loc, "Shape \"sphere\": radius too large for float (its area overflows)");
      } else {
        std::vector<Vec3> p, n;
        std::vector<Vec2> uv;
        std::vector<int> idx;
        TessellateSphere(radius, Clamp(zmin, -radius, radius), Clamp(zmax, -radius, radius),
                         Radians(Clamp(phimax, 0.f, 360.f)), &p, &n, &uv, &idx);
        SetMesh(&shape, d, std::move(p), std::move(n), std::move(uv), idx);
      }
    } else if (sd.type == "disk") {
      float height = ps.GetOneFloat("height", 0.f), radius = ps.GetOneFloat("radius", 1.f);
      float inner = ps.GetOneFloat("innerradius", 0.f), phimax = ps.GetOneFloat("phimax", 360.f);
      if (!(radius > 0) || inner < 0 || inner >= radius)
        throw SceneError(sd.loc, "Shape \"disk\": need 0 <= innerradius < radius");
      std::vector<Vec3> p, n;
      std::vector<Vec2> uv;
      std::vector<int> idx;
      TessellateDisk(height, radius, inner, Radians(Clamp(phimax, 0.f, 360.f)), &p, &n, &uv, &idx);
      SetMesh(&shape, d, std::move(p), std::move(n), std::move(uv), idx);
    } else {
      throw SceneError(sd.loc, "unsupported shape \"" + sd.type +
                                   "\" (supported: trianglemesh, plymesh, sphere, disk)");
    }
    ps.ReportUnused("Shape \"" + sd.type + "\"");
    if (shape.kind == ShapeKind::kTriangleMesh && shape.indices.empty()) {
      spdlog::warn("{}: shape has no non-degenerate triangles; skipped", shape.name);
      return;
    }
    if (sd.area_light) AddAreaEmitter(*sd.area_light, &shape);
    uint32_t index = uint32_t(s_.shapes_.size());
    if (shape.area_emitter >= 0) s_.area_emitters_[shape.area_emitter].shape = index;
    s_.shapes_.push_back(std::move(shape));
  }

  void AddAreaEmitter(const TypedEntity& al, Shape* shape) {
    if (al.type != "diffuse")
      throw SceneError(al.loc, "unsupported area light \"" + al.type + "\" (supported: diffuse)");
    const ParamSet& ps = al.params;
    AreaEmitter e;
    e.L = ps.GetOneRGB("L", SpectrumType::kIlluminant).value_or(RGB(1.f));
    float scale = ps.GetOneFloat("scale", 1.f);
    e.two_sided = ps.GetOneBool("twosided", false);
    if (ps.Has("filename"))
      throw SceneError(ps.Find("filename")->loc, "image area lights are not supported");
    // Area and per-triangle CDF.
    if (shape->kind == ShapeKind::kSphere) {
      e.area = 4 * kPi * shape->radius * shape->radius;
    } else {
      double total = 0;
      for (size_t t = 0; t < shape->indices.size(); t += 3) {
        Vec3 p0 = shape->positions[shape->indices[t]], p1 = shape->positions[shape->indices[t + 1]],
             p2 = shape->positions[shape->indices[t + 2]];
        total += 0.5 * double(Length(Cross(p1 - p0, p2 - p0)));
        e.triangle_cdf.push_back(float(total));
      }
      for (float& c : e.triangle_cdf) c = float(double(c) / total);
      e.area = float(total);
    }
    float power = ps.GetOneFloat("power", -1.f);
    if (power > 0) {
      // pbrt-v4: scale so that the emitted power equals "power" (luminance units).
      float k = (e.two_sided ? 2.f : 1.f) * e.area * kPi * e.L.Luminance();
      if (k > 0) scale *= power / k;
    }
    e.L *= scale;
    // Finite radiance over a finite but huge area can still overflow the power light
    // generation distributes (NaN sampling weights).
    if (!e.L.IsFinite() || !std::isfinite(e.area) || !e.Power().IsFinite())
      throw SceneError(al.loc, "AreaLightSource on " + shape->name +
                                   ": emitted power is not finite (radiance or area too large)");
    ps.ReportUnused("AreaLightSource \"diffuse\"");
    if (e.L.IsBlack() || e.area <= 0) return;  // emits nothing
    shape->area_emitter = int(s_.area_emitters_.size());
    s_.area_emitters_.push_back(std::move(e));
  }

  void AddLight(const LightDesc& ld) {
    const int medium = MediumIndex(ld.medium, ld.loc);
    if (medium >= 0) s_.has_media_ = true;
    const ParamSet& ps = ld.params;
    float scale = ps.GetOneFloat("scale", 1.f);
    const Transform& m = ld.world_from_light;
    if (ld.type == "point" || ld.type == "spot") {
      PointEmitter e;
      RGB I = ps.GetOneRGB("I", SpectrumType::kIlluminant).value_or(RGB(1.f));
      Vec3 from = ps.GetOnePoint3("from").value_or(Vec3{0, 0, 0});
      e.position = m.ApplyPoint(from);
      float power = ps.GetOneFloat("power", -1.f);
      if (ld.type == "spot") {
        Vec3 to = ps.GetOnePoint3("to").value_or(Vec3{0, 0, 1});
        float cone = ps.GetOneFloat("coneangle", 30.f), delta = ps.GetOneFloat("conedelta", 5.f);
        e.spot = true;
        e.axis = Normalize(m.ApplyVector(to - from));
        e.cos_falloff_end = std::cos(Radians(cone));
        e.cos_falloff_start = std::cos(Radians(cone - delta));
        if (power > 0) {
          float k = 2 * kPi * ((1 - e.cos_falloff_start) + (e.cos_falloff_start - e.cos_falloff_end) / 2);
          scale *= power / (k * I.Luminance());
        }
      } else if (power > 0) {
        scale *= power / (4 * kPi * I.Luminance());
      }
      e.intensity = I * scale;
      e.medium = medium;
      if (!IsFinite(e.position) || !IsFinite(e.axis))
        throw SceneError(ld.loc, "LightSource \"" + ld.type + "\": position/direction not finite");
      s_.point_emitters_.push_back(e);
    } else if (ld.type == "distant") {
      DistantEmitter e;
      e.medium = medium;
      RGB L = ps.GetOneRGB("L", SpectrumType::kIlluminant).value_or(RGB(1.f));
      Vec3 from = ps.GetOnePoint3("from").value_or(Vec3{0, 0, 0});
      Vec3 to = ps.GetOnePoint3("to").value_or(Vec3{0, 0, 1});
      Vec3 dir = m.ApplyVector(to - from);
      if (!(Length(dir) > 0)) throw SceneError(ld.loc, "LightSource \"distant\": from == to");
      e.direction = Normalize(dir);
      float illum = ps.GetOneFloat("illuminance", -1.f);
      if (illum > 0 && L.Luminance() > 0) scale *= illum / L.Luminance();
      e.L = L * scale;
      s_.distant_emitters_.push_back(e);
    } else if (ld.type == "infinite") {
      InfiniteEmitter e;
      e.medium = medium;
      e.world_from_light = m;
      auto inv = m.Inverse();
      if (!inv) throw SceneError(ld.loc, "LightSource \"infinite\": transform is singular");
      e.light_from_world = *inv;
      if (ps.Has("portal"))
        throw SceneError(ps.Find("portal")->loc, "infinite light portals are not supported");
      std::string file = ps.GetOneString("filename", "");
      auto L = ps.GetOneRGB("L", SpectrumType::kIlluminant);
      if (!file.empty() && L)
        throw SceneError(ld.loc, "LightSource \"infinite\": give either \"L\" or \"filename\"");
      if (!file.empty()) {
        Image img = ReadImage(desc_.ResolvePath(file));
        if (img.width != img.height)
          throw SceneError(ld.loc, "infinite light image \"" + file + "\" must be square (equal-area "
                                   "octahedral mapping, as pbrt-v4 requires); it is " +
                                   std::to_string(img.width) + "x" + std::to_string(img.height));
        e.width = img.width;
        e.height = img.height;
        e.image = std::move(img.pixels);
        double acc = 0;
        for (const RGB& c : e.image) {
          if (!c.IsFinite()) throw SceneError(ld.loc, "infinite light image has non-finite pixels");
          acc += double(std::max(c.Luminance(), 0.f)) + 1e-6;  // keep every direction samplable
          e.pixel_cdf.push_back(float(acc));
        }
      } else {
        e.L = L.value_or(RGB(1.f));
      }
      float illum = ps.GetOneFloat("illuminance", -1.f);
      if (illum > 0) {
        // Illuminance at an upward-facing point from the upper hemisphere = π · average radiance
        // for a uniform map; use that normalisation for images too (approximation, documented).
        float avg = e.AverageRadiance().Luminance();
        if (avg > 0) scale *= illum / (kPi * avg);
      }
      e.scale = RGB(scale);
      if (!(e.L * e.scale).IsFinite() || !(e.AverageRadiance() * e.scale).IsFinite())
        throw SceneError(ld.loc, "LightSource \"infinite\": radiance is not finite (L or scale too large)");
      s_.infinite_emitters_.push_back(std::move(e));
    } else {
      throw SceneError(ld.loc, "unsupported light \"" + ld.type +
                                   "\" (supported: point, spot, distant, infinite; area lights via "
                                   "AreaLightSource)");
    }
    ps.ReportUnused("LightSource \"" + ld.type + "\"");
  }

  void BuildEmbree() {
    s_.device_ = rtcNewDevice(nullptr);
    if (!s_.device_) throw std::runtime_error("Embree: cannot create device");
    rtcSetDeviceErrorFunction(
        s_.device_,
        [](void*, RTCError code, const char* str) {
          spdlog::error("Embree error {}: {}", int(code), str ? str : "");
        },
        nullptr);
    s_.rtc_scene_ = rtcNewScene(s_.device_);
    rtcSetSceneFlags(s_.rtc_scene_, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(s_.rtc_scene_, RTC_BUILD_QUALITY_HIGH);
    for (uint32_t i = 0; i < s_.shapes_.size(); ++i) {
      const Shape& sh = s_.shapes_[i];
      RTCGeometry geom;
      if (sh.kind == ShapeKind::kSphere) {
        geom = rtcNewGeometry(s_.device_, RTC_GEOMETRY_TYPE_SPHERE_POINT);
        float* v = static_cast<float*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), 1));
        v[0] = sh.center.x; v[1] = sh.center.y; v[2] = sh.center.z; v[3] = sh.radius;
        s_.bounds_.Extend(sh.center - Vec3(sh.radius, sh.radius, sh.radius));
        s_.bounds_.Extend(sh.center + Vec3(sh.radius, sh.radius, sh.radius));
      } else {
        geom = rtcNewGeometry(s_.device_, RTC_GEOMETRY_TYPE_TRIANGLE);
        float* v = static_cast<float*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
            sh.positions.size()));
        for (size_t k = 0; k < sh.positions.size(); ++k) {
          v[3 * k] = sh.positions[k].x;
          v[3 * k + 1] = sh.positions[k].y;
          v[3 * k + 2] = sh.positions[k].z;
          s_.bounds_.Extend(sh.positions[k]);
        }
        uint32_t* ix = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t),
            sh.indices.size() / 3));
        std::copy(sh.indices.begin(), sh.indices.end(), ix);
      }
      // Interface surfaces only change the medium: a separate mask keeps them out of shadow rays.
      bool interface = s_.materials_[sh.material].type == MaterialType::kInterface;
      rtcSetGeometryMask(geom, interface ? kMaskInterface : kMaskOpaque);
      rtcCommitGeometry(geom);
      rtcAttachGeometryByID(s_.rtc_scene_, geom, i);
      rtcReleaseGeometry(geom);
    }
    rtcCommitScene(s_.rtc_scene_);
    if (rtcGetDeviceError(s_.device_) != RTC_ERROR_NONE)
      throw std::runtime_error("Embree failed to build the scene BVH");
  }

  const SceneDescription& desc_;
  const SceneBuildOptions& opt_;
  Scene& s_;
  int default_material_ = -1;
  std::map<std::string, int> medium_index_;
};

std::unique_ptr<Scene> Scene::Build(const SceneDescription& desc, const SceneBuildOptions& opt) {
  std::unique_ptr<Scene> scene(new Scene());
  SceneBuilder(desc, opt, scene.get()).Build();
  return scene;
}

Scene::~Scene() {
  if (rtc_scene_) rtcReleaseScene(rtc_scene_);
  if (device_) rtcReleaseDevice(device_);
}

bool Scene::Intersect(const Ray& ray, SurfaceHit* hit, uint32_t mask) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh;
  rh.ray.org_x = ray.o.x; rh.ray.org_y = ray.o.y; rh.ray.org_z = ray.o.z;
  rh.ray.dir_x = ray.d.x; rh.ray.dir_y = ray.d.y; rh.ray.dir_z = ray.d.z;
  rh.ray.tnear = 0.f;
  rh.ray.tfar = ray.tmax;
  rh.ray.time = 0.f;
  rh.ray.mask = mask;  // Debian's Embree has ray masks on (DESIGN.md pitfalls)
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(rtc_scene_, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  const Shape& sh = shapes_[rh.hit.geomID];
  hit->shape = rh.hit.geomID;
  hit->prim = rh.hit.primID;
  hit->t = rh.ray.tfar;
  if (sh.kind == ShapeKind::kSphere) {
    // Reproject onto the sphere to remove the error of o + t·d.
    Vec3 p = ray.o + ray.d * rh.ray.tfar;
    Vec3 d = p - sh.center;
    float len = Length(d);
    Vec3 n = len > 0 ? d / len : Vec3{0, 0, 1};
    hit->p = sh.center + n * sh.radius;
    hit->ng = sh.flip_normals ? -n : n;
    hit->ns = hit->ng;
    hit->uv = {0.5f + std::atan2(n.y, n.x) * (0.5f * kInvPi), SafeAcos(n.z) * kInvPi};
    return true;
  }
  // Triangle: recompute the point from barycentrics (more accurate than o + t·d).
  uint32_t i0 = sh.indices[3 * rh.hit.primID], i1 = sh.indices[3 * rh.hit.primID + 1],
           i2 = sh.indices[3 * rh.hit.primID + 2];
  float b1 = rh.hit.u, b2 = rh.hit.v, b0 = 1 - b1 - b2;
  Vec3 p0 = sh.positions[i0], p1 = sh.positions[i1], p2 = sh.positions[i2];
  hit->p = p0 * b0 + p1 * b1 + p2 * b2;
  Vec3 ng = Normalize(Cross(p0 - p2, p1 - p2));  // pbrt-v4 triangle normal convention
  if (!sh.normals.empty()) {
    Vec3 ns = sh.normals[i0] * b0 + sh.normals[i1] * b1 + sh.normals[i2] * b2;
    float len = Length(ns);
    ns = len > 0 ? ns / len : ng;
    // With shading normals the geometric normal follows them (pbrt-v4).
    ng = FaceForward(ng, ns);
    hit->ns = ns;
  } else {
    if (sh.flip_normals) ng = -ng;
    hit->ns = ng;
  }
  hit->ng = ng;
  if (!sh.uvs.empty())
    hit->uv = sh.uvs[i0] * b0 + sh.uvs[i1] * b1 + sh.uvs[i2] * b2;
  else
    hit->uv = {b1, b2};
  return true;
}

void Scene::Occluded(RTCRay* rays, size_t count) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  // Shadow rays towards many lights are incoherent; COHERENT was ~3x slower (DESIGN.md).
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  for (size_t i = 0; i < count; ++i) rays[i].mask = kMaskOpaque;
  rtcOccluded1M(rtc_scene_, &ctx, rays, static_cast<unsigned int>(count), sizeof(RTCRay));
}

int Scene::MediumAfter(const SurfaceHit& hit, Vec3 w, int current) const {
  const Shape& sh = shapes_[hit.shape];
  if (!sh.medium_transition) return current;
  return Dot(w, hit.ng) > 0 ? sh.outside_medium : sh.inside_medium;
}

void Scene::MediumSegments(Vec3 o, Vec3 d, float tmax, int medium,
                           std::vector<MediumSegment>* out) const {
  if (!IsFinite(o) || !IsFinite(d) || !(tmax > 0)) return;
  float t = 0;
  Vec3 origin = o;
  // Each crossing restarts past the interface (offset along its normal); a bounded count
  // guards against a ray trapped by coplanar or degenerate interface geometry.
  for (int crossings = 0; crossings < 64; ++crossings) {
    float remaining = tmax - t;
    if (!(remaining > 0) || !IsFinite(origin)) return;
    SurfaceHit hit;
    if (!Intersect({origin, d, remaining}, &hit, kMaskInterface)) {
      out->push_back({t, tmax, medium});
      return;
    }
    float t_hit = std::min(t + hit.t, tmax);
    out->push_back({t, t_hit, medium});
    medium = MediumAfter(hit, d, medium);
    origin = OffsetRayOrigin(hit.p, hit.ng, d);
    t = t_hit;
  }
  if (t < tmax) out->push_back({t, tmax, medium});
}

RGB Scene::Transmittance(Vec3 p0, Vec3 p1, int medium, Rng& rng) const {
  Vec3 d = p1 - p0;
  float len = Length(d);
  if (!(len > 0) || !std::isfinite(len)) return RGB(len == 0.f ? 1.f : 0.f);
  return TransmittanceAlong(p0, d / len, len, medium, rng);
}

RGB Scene::TransmittanceAlong(Vec3 o, Vec3 d, float tmax, int medium, Rng& rng) const {
  if (media_.empty()) return RGB(1.f);
  if (!IsFinite(o) || !IsFinite(d) || std::isnan(tmax)) return RGB(0.f);
  std::vector<MediumSegment> segments;
  MediumSegments(o, d, tmax, medium, &segments);
  RGB T(1.f);
  for (const MediumSegment& s : segments) {
    if (s.medium < 0 || !(s.t1 > s.t0)) continue;
    T *= media_[s.medium].Transmittance({o + d * s.t0, d, s.t1 - s.t0}, rng);
    if (T.IsBlack()) break;
  }
  return T;
}

RGB Scene::EmittedRadiance(const SurfaceHit& hit, Vec3 w) const {
  int e = shapes_[hit.shape].area_emitter;
  if (e < 0) return RGB(0.f);
  const AreaEmitter& em = area_emitters_[e];
  if (!em.two_sided && Dot(hit.ng, w) <= 0) return RGB(0.f);
  return em.L;
}

RGB Scene::EnvironmentRadiance(Vec3 d) const {
  RGB L(0.f);
  for (const InfiniteEmitter& e : infinite_emitters_) L += e.Le(d);
  return L;
}

void Scene::SetSharpAlpha(float alpha, float near_max_alpha) {
  if (near_twins_.empty()) own_materials_ = materials_.size();
  materials_.resize(own_materials_);
  near_twins_.assign(own_materials_, -1);
  for (Material& m : materials_) m.sharp_alpha = alpha;
  if (!(near_max_alpha > 0)) return;
  for (size_t i = 0; i < own_materials_; ++i) {
    const Material& m = materials_[i];
    if (!HasRoughMicrofacetLobe(m) || std::max(m.alpha_x, m.alpha_y) > near_max_alpha) continue;
    Material twin = m;
    twin.sharp_alpha = std::numeric_limits<float>::infinity();
    twin.name += " (near-field sharp)";
    near_twins_[i] = int(materials_.size());
    materials_.push_back(std::move(twin));
  }
}

void Scene::SampleAreaEmitter(const AreaEmitter& e, Vec2 u, Vec3* p, Vec3* n) const {
  const Shape& sh = shapes_[e.shape];
  if (sh.kind == ShapeKind::kSphere) {
    Vec3 d = SampleUniformSphere(u);
    *p = sh.center + d * sh.radius;
    *n = sh.flip_normals ? -d : d;
    return;
  }
  size_t t = std::upper_bound(e.triangle_cdf.begin(), e.triangle_cdf.end(), u.x) -
             e.triangle_cdf.begin();
  t = std::min(t, e.triangle_cdf.size() - 1);
  float lo = t == 0 ? 0.f : e.triangle_cdf[t - 1];
  float width = e.triangle_cdf[t] - lo;
  u.x = width > 0 ? Clamp((u.x - lo) / width, 0.f, 0x1.fffffep-1f) : 0.5f;
  float b0, b1;
  SampleUniformTriangle(u, &b0, &b1);
  uint32_t i0 = sh.indices[3 * t], i1 = sh.indices[3 * t + 1], i2 = sh.indices[3 * t + 2];
  Vec3 p0 = sh.positions[i0], p1 = sh.positions[i1], p2 = sh.positions[i2];
  *p = p0 * b0 + p1 * b1 + p2 * (1 - b0 - b1);
  Vec3 ng = Normalize(Cross(p0 - p2, p1 - p2));
  if (!sh.normals.empty()) {
    Vec3 ns = sh.normals[i0] * b0 + sh.normals[i1] * b1 + sh.normals[i2] * (1 - b0 - b1);
    ng = FaceForward(ng, ns);
  } else if (sh.flip_normals) {
    ng = -ng;
  }
  *n = ng;
}

}  // namespace lightfarm
