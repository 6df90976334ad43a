// A scene with caustics for the tests that need one (tests/unit/test_caustics.cpp, the farm
// tests): a square light above a sphere above a diffuse floor, seen at an angle; the sphere is
// glass or diffuse, and `fog` fills a box around them with a scattering medium.
#pragma once

#include <string>

namespace lightfarm::testing {

inline std::string SphereOverFloor(bool glass, bool fog) {
  std::string s =
      "Film \"rgb\" \"integer xresolution\" [40] \"integer yresolution\" [40]\nPixelFilter \"box\"\n"
      "Integrator \"volpath\" \"integer maxdepth\" [5]\n"
      "LookAt 0 3 3.5  0 0.3 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\n";
  if (fog) s += "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.05 0.05 0.05] "
                "\"rgb sigma_s\" [0.4 0.4 0.4] \"float scale\" 1\n";
  s += "WorldBegin\n";
  if (fog) {
    // The fog's box: an interface with the fog inside (its normals point out, the side
    // MediumInterface calls exterior); the camera sits outside it.
    s += "AttributeBegin\nMediumInterface \"fog\" \"\"\nMaterial \"interface\"\n"
         "Shape \"trianglemesh\" \"point3 P\" [-2 0.001 -2  2 0.001 -2  2 0.001 2  -2 0.001 2  "
         "-2 2.5 -2  2 2.5 -2  2 2.5 2  -2 2.5 2]\n"
         "  \"integer indices\" [0 1 2 0 2 3  4 6 5 4 7 6  0 4 5 0 5 1  3 2 6 3 6 7  0 3 7 0 7 4  1 5 6 1 6 2]\n"
         "AttributeEnd\n";
    s += "AttributeBegin\nMediumInterface \"fog\" \"fog\"\n";
  } else {
    s += "AttributeBegin\n";
  }
  s += "AreaLightSource \"diffuse\" \"rgb L\" [30 30 30]\nMaterial \"diffuse\" \"rgb reflectance\" [0 0 0]\n"
       "Shape \"trianglemesh\" \"point3 P\" [-0.4 2.4 -0.4  0.4 2.4 -0.4  0.4 2.4 0.4  -0.4 2.4 0.4]\n"
       "  \"integer indices\" [0 1 2 0 2 3]\nAttributeEnd\n";
  // The glass holds no fog.
  if (fog) s += "AttributeBegin\nMediumInterface \"\" \"fog\"\n";
  else s += "AttributeBegin\n";
  s += glass ? "Material \"dielectric\" \"float eta\" 1.5\n" : "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n";
  s += "Translate 0 0.9 0\nShape \"sphere\" \"float radius\" 0.45\nAttributeEnd\n";
  s += "Material \"diffuse\" \"rgb reflectance\" [0.6 0.6 0.6]\n"
       "Shape \"trianglemesh\" \"point3 P\" [-3 0 -3  3 0 -3  3 0 3  -3 0 3]\n"
       "  \"integer indices\" [0 2 1 0 3 2]\n";
  return s;
}

}  // namespace lightfarm::testing
