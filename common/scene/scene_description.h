// What a pbrt-v4 scene file says, parsed but not yet built: directives with their parameter
// lists, the transforms in force and the file:line they came from. The builder (scene.h)
// turns this into Embree geometry, materials, emitters and a camera, reporting unsupported
// features and unused parameters with those locations.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/scene/params.h"
#include "common/util/transform.h"

namespace lightfarm {

// A directive with a type name and parameters: Camera "perspective" ..., Film "rgb" ...
struct TypedEntity {
  std::string type;
  ParamSet params;
  FileLoc loc;
};

struct CameraDesc : TypedEntity {
  Transform camera_from_world;  // the CTM when Camera appeared
  std::string medium;           // the outside medium in force (MediumInterface), "" for none
};

struct MaterialDesc : TypedEntity {
  std::string name;  // "" for anonymous Material directives
};

struct TextureDesc : TypedEntity {
  std::string name;
  std::string value_type;  // "float" or "spectrum"
  Transform world_from_texture;
};

struct MediumDesc : TypedEntity {
  std::string name;
  Transform world_from_medium;
};

struct ShapeDesc : TypedEntity {
  Transform world_from_object;
  bool reverse_orientation = false;
  // Index into SceneDescription::materials. -1: no Material/NamedMaterial in force, which means
  // pbrt-v4's default material, "diffuse" with reflectance 0.5 (not added to `materials`).
  int material = -1;
  std::optional<TypedEntity> area_light;  // AreaLightSource in force
  std::string inside_medium, outside_medium;
};

struct LightDesc : TypedEntity {
  Transform world_from_light;
  std::string medium;  // outside medium in force
};

struct InstanceUse {
  std::string name;
  Transform world_from_instance;
  FileLoc loc;
};

struct SceneDescription {
  std::string root_file;  // path as given
  std::string base_dir;   // directory that relative file names resolve against
  std::vector<std::string> files;  // every file read: root, includes, referenced PLY/images

  CameraDesc camera;  // type "perspective" with defaults if the file has no Camera
  TypedEntity film, filter, sampler, integrator, accelerator;
  bool has_camera = false;

  std::vector<MaterialDesc> materials;  // named and anonymous, in order of appearance
  std::map<std::string, int> named_materials;
  std::map<std::string, TextureDesc> textures;
  std::map<std::string, MediumDesc> media;
  std::vector<ShapeDesc> shapes;
  std::vector<LightDesc> lights;
  std::map<std::string, std::vector<ShapeDesc>> instance_definitions;
  std::vector<InstanceUse> instance_uses;

  // Resolves a file name from the scene (PLY, image) against base_dir.
  std::string ResolvePath(const std::string& name) const;
};

// Parses a pbrt-v4 file and everything it includes. Throws SceneError with file:line.
SceneDescription ParseSceneFile(const std::string& path);
// Parses scene text held in memory; `filename` names it in errors, includes resolve against
// base_dir.
SceneDescription ParseSceneString(const std::string& text, const std::string& filename,
                                  const std::string& base_dir);

}  // namespace lightfarm
