// ParamSet: typed lookups over a directive's parameter list, with pbrt-v4's type synonyms,
// value-count checks and used-marking so that ReportUnused() can name every parameter nobody
// asked for.
#include "common/scene/params.h"

#include <cmath>
#include <limits>

namespace lightfarm {

namespace {

std::string Quoted(const std::string& s) { return "\"" + s + "\""; }

[[noreturn]] void CountError(const Param& p, const std::string& expectation) {
  throw SceneError(p.loc, "parameter " + Quoted(p.name) + " (" + p.type + ") " + expectation +
                              ", got " +
                              std::to_string(p.numbers.size() + p.strings.size() + p.bools.size()));
}

// Exactly one value of the kind stored in `values`.
template <typename T>
void RequireOne(const Param& p, const std::vector<T>& values) {
  if (values.size() != 1) CountError(p, "needs exactly one value");
}

// A multiple of `n` numbers (point3 arrays and the like).
void RequireMultipleOf(const Param& p, size_t n) {
  if (!p.strings.empty() || !p.bools.empty() || p.numbers.size() % n != 0)
    CountError(p, "needs a multiple of " + std::to_string(n) + " numbers");
}

int ToInt(const Param& p, double v) {
  // The parser already insists on integral values; a ParamSet assembled in code gets the same
  // check so an int lookup never truncates silently.
  if (v != std::floor(v) || v < double(std::numeric_limits<int>::min()) ||
      v > double(std::numeric_limits<int>::max()))
    throw SceneError(p.loc, "parameter " + Quoted(p.name) + " value " + std::to_string(v) +
                                " is not a 32-bit integer");
  return static_cast<int>(v);
}

std::string FormatRGB(RGB c) {
  return "(" + std::to_string(c.r) + ", " + std::to_string(c.g) + ", " + std::to_string(c.b) + ")";
}

// Reflectances above 1 create energy, negative values of any kind are meaningless; both are
// errors at the parameter rather than NaNs or fireflies much later.
void CheckSpectrumRange(const Param& p, RGB c, SpectrumType type) {
  if (!c.IsFinite())
    throw SceneError(p.loc, "parameter " + Quoted(p.name) + " is not finite: " + FormatRGB(c));
  if (c.r < 0 || c.g < 0 || c.b < 0)
    throw SceneError(p.loc,
                     "parameter " + Quoted(p.name) + " has a negative component " + FormatRGB(c));
  if (type == SpectrumType::kAlbedo && (c.r > 1 || c.g > 1 || c.b > 1))
    throw SceneError(p.loc, "parameter " + Quoted(p.name) + " is a reflectance and must lie in " +
                                "[0, 1], got " + FormatRGB(c));
}

}  // namespace

void ParamSet::Add(Param p) {
  for (Param& existing : params_) {
    if (existing.name == p.name) {
      existing = std::move(p);
      return;
    }
  }
  params_.push_back(std::move(p));
}

const Param* ParamSet::Lookup(const std::string& name, std::initializer_list<const char*> types,
                              const char* wanted) const {
  const Param* p = Find(name);
  if (!p) return nullptr;
  // `types` lists the canonical type and its pbrt-v3 spellings ("point3", "point"), so files
  // written for either version are accepted.
  for (const char* t : types) {
    if (p->type == t) {
      p->used = true;
      return p;
    }
  }
  throw SceneError(p->loc, "parameter " + Quoted(name) + " is " + p->type + ", expected " + wanted);
}

float ParamSet::GetOneFloat(const std::string& name, float def) const {
  const Param* p = Lookup(name, {"float"}, "float");
  if (!p) return def;
  RequireOne(*p, p->numbers);
  return static_cast<float>(p->numbers[0]);
}

int ParamSet::GetOneInt(const std::string& name, int def) const {
  const Param* p = Lookup(name, {"integer"}, "integer");
  if (!p) return def;
  RequireOne(*p, p->numbers);
  return ToInt(*p, p->numbers[0]);
}

bool ParamSet::GetOneBool(const std::string& name, bool def) const {
  const Param* p = Lookup(name, {"bool"}, "bool");
  if (!p) return def;
  RequireOne(*p, p->bools);
  return p->bools[0];
}

std::string ParamSet::GetOneString(const std::string& name, const std::string& def) const {
  const Param* p = Lookup(name, {"string"}, "string");
  if (!p) return def;
  RequireOne(*p, p->strings);
  return p->strings[0];
}

std::optional<Vec3> ParamSet::GetOnePoint3(const std::string& name) const {
  const Param* p = Lookup(name, {"point3", "point"}, "point3");
  if (!p) return std::nullopt;
  if (p->numbers.size() != 3) CountError(*p, "needs exactly 3 numbers");
  return Vec3(static_cast<float>(p->numbers[0]), static_cast<float>(p->numbers[1]),
              static_cast<float>(p->numbers[2]));
}

std::optional<Vec3> ParamSet::GetOneVector3(const std::string& name) const {
  const Param* p = Lookup(name, {"vector3", "vector"}, "vector3");
  if (!p) return std::nullopt;
  if (p->numbers.size() != 3) CountError(*p, "needs exactly 3 numbers");
  return Vec3(static_cast<float>(p->numbers[0]), static_cast<float>(p->numbers[1]),
              static_cast<float>(p->numbers[2]));
}

std::vector<float> ParamSet::GetFloatArray(const std::string& name) const {
  const Param* p = Lookup(name, {"float"}, "float");
  if (!p) return {};
  RequireMultipleOf(*p, 1);
  std::vector<float> out;
  out.reserve(p->numbers.size());
  for (double v : p->numbers) out.push_back(static_cast<float>(v));
  return out;
}

std::vector<int> ParamSet::GetIntArray(const std::string& name) const {
  const Param* p = Lookup(name, {"integer"}, "integer");
  if (!p) return {};
  RequireMultipleOf(*p, 1);
  std::vector<int> out;
  out.reserve(p->numbers.size());
  for (double v : p->numbers) out.push_back(ToInt(*p, v));
  return out;
}

namespace {

std::vector<Vec3> ToVec3s(const Param& p) {
  RequireMultipleOf(p, 3);
  std::vector<Vec3> out;
  out.reserve(p.numbers.size() / 3);
  for (size_t i = 0; i + 2 < p.numbers.size(); i += 3)
    out.emplace_back(static_cast<float>(p.numbers[i]), static_cast<float>(p.numbers[i + 1]),
                     static_cast<float>(p.numbers[i + 2]));
  return out;
}

}  // namespace

std::vector<Vec3> ParamSet::GetPoint3Array(const std::string& name) const {
  const Param* p = Lookup(name, {"point3", "point"}, "point3");
  return p ? ToVec3s(*p) : std::vector<Vec3>{};
}

std::vector<Vec3> ParamSet::GetNormalArray(const std::string& name) const {
  const Param* p = Lookup(name, {"normal3", "normal"}, "normal3");
  return p ? ToVec3s(*p) : std::vector<Vec3>{};
}

std::vector<Vec2> ParamSet::GetPoint2Array(const std::string& name) const {
  const Param* p = Lookup(name, {"point2"}, "point2");
  if (!p) return {};
  RequireMultipleOf(*p, 2);
  std::vector<Vec2> out;
  out.reserve(p->numbers.size() / 2);
  for (size_t i = 0; i + 1 < p->numbers.size(); i += 2)
    out.emplace_back(static_cast<float>(p->numbers[i]), static_cast<float>(p->numbers[i + 1]));
  return out;
}

std::optional<RGB> ParamSet::GetOneRGB(const std::string& name, SpectrumType type) const {
  // "float" is accepted because pbrt-v4 allows a constant wherever a spectrum is expected
  // ("float eta" 1.5 on a dielectric).
  const Param* p = Lookup(name, {"rgb", "color", "blackbody", "spectrum", "float"},
                          "rgb, blackbody, spectrum or float");
  if (!p) return std::nullopt;

  RGB result;
  if (p->type == "rgb" || p->type == "color") {
    if (p->numbers.size() != 3) CountError(*p, "needs exactly 3 numbers");
    result = RGB(static_cast<float>(p->numbers[0]), static_cast<float>(p->numbers[1]),
                 static_cast<float>(p->numbers[2]));
  } else if (p->type == "float") {
    RequireOne(*p, p->numbers);
    result = RGB(static_cast<float>(p->numbers[0]));
  } else if (p->type == "blackbody") {
    RequireOne(*p, p->numbers);
    double kelvin = p->numbers[0];
    if (!(kelvin > 0) || kelvin > double(std::numeric_limits<float>::max()))
      throw SceneError(p->loc, "parameter " + Quoted(name) +
                                   ": blackbody temperature must be positive kelvin, got " +
                                   std::to_string(kelvin));
    result = BlackbodyToRGB(static_cast<float>(kelvin));
  } else {  // "spectrum": one named spectrum or (lambda, value) pairs
    if (!p->strings.empty()) {
      RequireOne(*p, p->strings);
      std::optional<RGB> named = NamedSpectrumToRGB(p->strings[0]);
      if (!named)
        throw SceneError(p->loc, "parameter " + Quoted(name) + ": unknown named spectrum " +
                                     Quoted(p->strings[0]) + " (spectrum files are not supported)");
      result = *named;
    } else {
      if (p->numbers.size() < 2 || p->numbers.size() % 2 != 0)
        CountError(*p, "needs (wavelength, value) pairs");
      for (size_t i = 2; i < p->numbers.size(); i += 2)
        if (!(p->numbers[i] > p->numbers[i - 2]))
          throw SceneError(p->loc, "parameter " + Quoted(name) +
                                       ": spectrum wavelengths must increase, got " +
                                       std::to_string(p->numbers[i - 2]) + " then " +
                                       std::to_string(p->numbers[i]));
      if (type == SpectrumType::kAlbedo)
        for (size_t i = 1; i < p->numbers.size(); i += 2)
          if (p->numbers[i] < 0 || p->numbers[i] > 1)
            throw SceneError(p->loc, "parameter " + Quoted(name) +
                                         " is a reflectance spectrum and its values must lie in "
                                         "[0, 1], got " +
                                         std::to_string(p->numbers[i]));
      result = SampledSpectrumToRGB(p->numbers, type);
    }
  }
  CheckSpectrumRange(*p, result, type);
  return result;
}

std::string ParamSet::GetTexture(const std::string& name) const {
  const Param* p = Lookup(name, {"texture"}, "texture");
  if (!p) return "";
  RequireOne(*p, p->strings);
  return p->strings[0];
}

bool ParamSet::Has(const std::string& name) const { return Find(name) != nullptr; }

const Param* ParamSet::Find(const std::string& name) const {
  // Linear search: parameter lists hold a handful of entries.
  for (const Param& p : params_)
    if (p.name == name) return &p;
  return nullptr;
}

void ParamSet::ReportUnused(const std::string& context) const {
  for (const Param& p : params_)
    if (!p.used)
      throw SceneError(p.loc,
                       "unused parameter " + Quoted(p.type + " " + p.name) + " in " + context);
}

void ParamSet::AddDefaults(const ParamSet& defaults) {
  for (const Param& d : defaults.params_) {
    if (Has(d.name)) continue;
    Param copy = d;
    // A default applies to every entity of its category, and most of them will not take it
    // ("float radius" on a trianglemesh); pbrt-v4 exempts such parameters from the unused
    // check (mayBeUnused), which pre-marking them used does here.
    copy.used = true;
    params_.push_back(std::move(copy));
  }
}

}  // namespace lightfarm
