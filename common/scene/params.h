// Typed parameter lists of pbrt-v4 directives ("float fov" [ 45 ], "rgb L" [ 1 2 3 ], ...).
// Every lookup marks the parameter used; after an object is built, ReportUnused() turns a
// parameter nobody asked for into an error with its file:line, as pbrt-v4 does, so a typo
// ("sigmaa") or an unsupported feature is never silently skipped.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "common/util/error.h"
#include "common/util/math.h"

namespace lightfarm {

// How an RGB or spectral value will be used; decides clamping and spectrum conversion.
enum class SpectrumType {
  kAlbedo,      // reflectances: must lie in [0, 1]
  kUnbounded,   // eta, k, sigma_a, ...
  kIlluminant,  // emission
};

struct Param {
  std::string type;  // as written: "float", "integer", "rgb", "point3", "normal", ...
  std::string name;
  FileLoc loc;
  std::vector<double> numbers;  // float, integer, point*, vector*, normal*, rgb, blackbody, spectrum pairs
  std::vector<std::string> strings;  // string, texture, spectrum (named)
  std::vector<bool> bools;
  mutable bool used = false;
};

class ParamSet {
 public:
  // Adds a parameter. A second parameter of the same name replaces the first (pbrt-v4).
  void Add(Param p);
  bool Empty() const { return params_.empty(); }
  const std::vector<Param>& params() const { return params_; }

  // Single values. A present parameter of the wrong type or with the wrong number of values
  // throws SceneError at the parameter's location.
  float GetOneFloat(const std::string& name, float def) const;
  int GetOneInt(const std::string& name, int def) const;
  bool GetOneBool(const std::string& name, bool def) const;
  std::string GetOneString(const std::string& name, const std::string& def) const;
  std::optional<Vec3> GetOnePoint3(const std::string& name) const;
  std::optional<Vec3> GetOneVector3(const std::string& name) const;

  // Arrays.
  std::vector<float> GetFloatArray(const std::string& name) const;
  std::vector<int> GetIntArray(const std::string& name) const;
  std::vector<Vec3> GetPoint3Array(const std::string& name) const;
  std::vector<Vec3> GetNormalArray(const std::string& name) const;
  std::vector<Vec2> GetPoint2Array(const std::string& name) const;

  // A colour given as "rgb", "blackbody" or "spectrum" (named or wavelength/value pairs),
  // converted to linear sRGB. nullopt if absent.
  std::optional<RGB> GetOneRGB(const std::string& name, SpectrumType type) const;

  // Name of a texture bound with "texture NAME", or empty.
  std::string GetTexture(const std::string& name) const;

  // True if a parameter of this name exists (any type). Does not mark it used.
  bool Has(const std::string& name) const;
  const Param* Find(const std::string& name) const;

  // Throws SceneError for the first parameter never looked up:
  //   file:line: unused parameter "float sigmaa" in MakeNamedMedium "homogeneous"
  void ReportUnused(const std::string& context) const;

  // Merges defaults (from the Attribute directive): parameters not present here are added.
  void AddDefaults(const ParamSet& defaults);

 private:
  const Param* Lookup(const std::string& name, std::initializer_list<const char*> types,
                      const char* wanted) const;
  std::vector<Param> params_;
};

// Linear sRGB of a blackbody at temperature kelvin, normalised so that its maximum is 1
// (pbrt-v4's BlackbodySpectrum normalisation, then projected to RGB).
RGB BlackbodyToRGB(float kelvin);
// Linear sRGB of a piecewise-linear spectrum given as (lambda nm, value) pairs.
RGB SampledSpectrumToRGB(const std::vector<double>& lambda_value_pairs, SpectrumType type);
// Linear sRGB of a pbrt-v4 named spectrum ("metal-Cu-eta", "glass-BK7", ...); nullopt if unknown.
std::optional<RGB> NamedSpectrumToRGB(const std::string& name);

}  // namespace lightfarm
