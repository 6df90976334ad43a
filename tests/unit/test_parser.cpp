// Tests for the pbrt-v4 parser, ParamSet and the spectrum conversions: every error carries the
// right file:line, transforms compose as in pbrt, graphics state is scoped as in pbrt, and the
// shared scenes parse to the counts their files show.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "common/scene/params.h"
#include "common/scene/scene_description.h"

namespace lightfarm {
namespace test_parser {

namespace fs = std::filesystem;

// A fresh directory per test for Include targets and referenced files.
class ParserTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static int counter = 0;
    dir_ = fs::temp_directory_path() /
           ("lightfarm_parser_test_" + std::to_string(getpid()) + "_" + std::to_string(counter++));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  std::string Write(const std::string& name, const std::string& text) {
    fs::path p = dir_ / name;
    fs::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }

  SceneDescription Parse(const std::string& text) {
    return ParseSceneString(text, "test.pbrt", dir_.string());
  }

  // Parses `text` and expects a SceneError at test.pbrt:`line` whose message contains `what`.
  void ExpectError(const std::string& text, int line, const std::string& what) {
    ExpectErrorIn([&] { Parse(text); }, "test.pbrt:" + std::to_string(line) + ":", what);
  }

  template <typename F>
  static void ExpectErrorIn(F&& f, const std::string& prefix, const std::string& what) {
    try {
      f();
      ADD_FAILURE() << "expected a SceneError starting with " << prefix << " containing " << what;
    } catch (const SceneError& e) {
      std::string msg = e.what();
      EXPECT_EQ(msg.rfind(prefix, 0), 0u) << "message: " << msg << "\nexpected prefix: " << prefix;
      EXPECT_NE(msg.find(what), std::string::npos) << "message: " << msg << "\nexpected: " << what;
    }
  }

  fs::path dir_;
};

void ExpectNear(Vec3 a, Vec3 b, float eps = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, eps);
  EXPECT_NEAR(a.y, b.y, eps);
  EXPECT_NEAR(a.z, b.z, eps);
}

// --- Errors name file:line -------------------------------------------------------------------

TEST_F(ParserTest, UnknownDirective) {
  ExpectError("WorldBegin\n\n  Foo 1 2\n", 3, "unknown directive \"Foo\"");
  ExpectError("WorldBegin\nWorldEnd\n", 2, "unknown directive \"WorldEnd\"");
  ExpectError("WorldBegin\n[ 1 ]\n", 2, "expected a directive");
}

TEST_F(ParserTest, LineNumbersSurviveCommentsAndCRLF) {
  ExpectError("# comment \"with quote\n\r\nWorldBegin # trailing\r\n\r\nBogus\r\n", 5,
              "unknown directive \"Bogus\"");
}

TEST_F(ParserTest, WrongParamTypeAtLookup) {
  SceneDescription s = Parse("Camera \"perspective\"\n    \"float fov\" [ 45 ]\nWorldBegin\n");
  ExpectErrorIn([&] { s.camera.params.GetOneInt("fov", 0); },
                "test.pbrt:2:", "parameter \"fov\" is float, expected integer");
  EXPECT_FLOAT_EQ(s.camera.params.GetOneFloat("fov", 0), 45.f);
}

TEST_F(ParserTest, WrongValueCount) {
  ExpectError("WorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\"\n  \"rgb L\" [ 1 2 ]\n", 4,
              "needs exactly 3 numbers");
  ExpectError("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [ 0 0 0 1 ]\n", 2, "multiple of 3");
  ExpectError("WorldBegin\nShape \"sphere\" \"float radius\" [ ]\n", 2, "at least one value");
}

TEST_F(ParserTest, BadParameterDeclarations) {
  ExpectError("WorldBegin\nShape \"sphere\"\n \"floaty radius\" 1\n", 3, "unknown parameter type");
  ExpectError("WorldBegin\nShape \"sphere\" \"radius\" 1\n", 2, "must be \"type name\"");
  ExpectError("WorldBegin\nShape \"sphere\" \"float radius\" \"one\"\n", 2, "expects numbers");
  ExpectError("WorldBegin\nShape \"trianglemesh\"\n\"integer indices\" [ 0 1 2.5 ]\n", 3,
              "expects integers");
  ExpectError("WorldBegin\nShape \"sphere\" \"bool flip\" maybe\n", 2, "true or false");
  ExpectError("WorldBegin\nShape \"sphere\" \"float radius\" 1\n  \"float radius\" 2\n", 3,
              "given twice");
  ExpectError("WorldBegin\nShape \"sphere\" \"float radius\" [ 1 2\n", 2, "unclosed \"[\"");
}

TEST_F(ParserTest, MissingInclude) {
  ExpectError("WorldBegin\n\nInclude \"nope.pbrt\"\n", 3, "does not exist");
}

TEST_F(ParserTest, RecursiveInclude) {
  Write("a.pbrt", "# a\nInclude \"b.pbrt\"\n");
  std::string b = Write("b.pbrt", "\n\nInclude \"a.pbrt\"\n");
  ExpectErrorIn([&] { Parse("WorldBegin\nInclude \"a.pbrt\"\n"); }, b + ":3:", "recursive Include");
  std::string self = Write("self.pbrt", "WorldBegin\nInclude \"self.pbrt\"\n");
  ExpectErrorIn([&] { ParseSceneFile(self); }, self + ":2:", "recursive Include");
}

TEST_F(ParserTest, IncludeDepthAndCountAreCapped) {
  // 40 distinct files, each including the next: not a cycle, but too deep.
  for (int i = 0; i < 40; ++i)
    Write("d" + std::to_string(i) + ".pbrt", "Include \"d" + std::to_string(i + 1) + ".pbrt\"\n");
  Write("d40.pbrt", "\n");
  ExpectErrorIn([&] { Parse("WorldBegin\nInclude \"d0.pbrt\"\n"); }, dir_.string(),
                "nested deeper than 32");
  // Each level includes the next twice: 2^24 includes unless capped.
  for (int i = 0; i < 24; ++i) {
    std::string next = "e" + std::to_string(i + 1) + ".pbrt";
    Write("e" + std::to_string(i) + ".pbrt",
          "Include \"" + next + "\"\nInclude \"" + next + "\"\n");
  }
  Write("e24.pbrt", "\n");
  ExpectErrorIn([&] { Parse("WorldBegin\nInclude \"e0.pbrt\"\n"); }, dir_.string(),
                "Include/Import directives");
}

TEST_F(ParserTest, UnterminatedString) {
  ExpectError("WorldBegin\nShape \"sphere\"\n  \"float radius 1\nShape \"sphere\"\n", 3,
              "unterminated string");
  ExpectError("WorldBegin\n\nShape \"sphere", 3, "unterminated string");
  ExpectError("WorldBegin\nShape \"sph\\qere\"\n", 2, "escape");
  SceneDescription s =
      Parse("WorldBegin\nShape \"plymesh\" \"string filename\" \"a\\\"b\\\\c\\td\"\n");
  EXPECT_EQ(s.shapes[0].params.GetOneString("filename", ""), "a\"b\\c\td");
}

TEST_F(ParserTest, MalformedAndHugeNumbers) {
  ExpectError("WorldBegin\nShape \"sphere\"\n  \"float radius\" 1e999\n", 3, "number out of range");
  ExpectError("WorldBegin\nShape \"sphere\" \"float radius\" 1e39\n", 2, "number out of range");
  ExpectError("WorldBegin\nTranslate 1 2.3.4 5\n", 2, "malformed number \"2.3.4\"");
  ExpectError("WorldBegin\nTranslate 1 nan 5\n", 2, "not finite");
  ExpectError("WorldBegin\nTranslate 1 2\n", 2, "end of file");
  // Underflow is a harmless zero, not an error; a leading '+' is accepted.
  SceneDescription s = Parse(
      "WorldBegin\nShape \"sphere\" \"float radius\" [ 1e-400 ]\n"
      "Shape \"sphere\" \"float radius\" +2.5\n");
  EXPECT_EQ(s.shapes[0].params.GetOneFloat("radius", 1), 0.f);
  EXPECT_EQ(s.shapes[1].params.GetOneFloat("radius", 1), 2.5f);
}

TEST_F(ParserTest, UnbalancedBlocks) {
  ExpectError("WorldBegin\nAttributeBegin\nAttributeEnd\nAttributeEnd\n", 4,
              "without a matching AttributeBegin");
  ExpectError("WorldBegin\nAttributeBegin\n\nAttributeBegin\nAttributeEnd\n", 2,
              "AttributeBegin is never closed");
  ExpectError("WorldBegin\nTransformBegin\nAttributeEnd\n", 3, "closes TransformBegin");
  ExpectError("WorldBegin\nObjectBegin \"a\"\nObjectBegin \"b\"\n", 3, "inside ObjectBegin");
  ExpectError("WorldBegin\nObjectEnd\n", 2, "ObjectEnd without");
}

TEST_F(ParserTest, UnknownNamedMaterialAndMedium) {
  ExpectError(
      "WorldBegin\nMakeNamedMaterial \"a\" \"string type\" \"diffuse\"\n"
      "NamedMaterial \"b\"\n",
      3, "unknown named material \"b\"");
  // The MediumInterface is reported, once a shape uses it.
  ExpectError("WorldBegin\nMediumInterface \"fog\" \"\"\n\nShape \"sphere\"\n", 2,
              "unknown medium \"fog\"");
  EXPECT_NO_THROW(Parse("WorldBegin\nMediumInterface \"unused\"\n"));
  // Defined after the MediumInterface but before the end: fine, as in pbrt-v4.
  EXPECT_NO_THROW(
      Parse("WorldBegin\nMediumInterface \"fog\"\nShape \"sphere\"\n"
            "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\"\n"));
}

TEST_F(ParserTest, UnknownInstance) {
  ExpectError("WorldBegin\n\nObjectInstance \"ghost\"\n", 3, "unknown object \"ghost\"");
  // pbrt-v4 allows use before definition.
  SceneDescription s = Parse(
      "WorldBegin\nObjectInstance \"later\"\nObjectBegin \"later\"\n"
      "Shape \"sphere\"\nObjectEnd\n");
  EXPECT_EQ(s.instance_uses.size(), 1u);
}

TEST_F(ParserTest, UnusedParameterReportedByBuilder) {
  SceneDescription s = Parse(
      "WorldBegin\nMakeNamedMedium \"smoke\"\n"
      "  \"string type\" \"homogeneous\"\n"
      "  \"rgb sigma_a\" [ 1 1 1 ]\n"
      "  \"float sigmaa\" 2\n");
  const MediumDesc& m = s.media.at("smoke");
  EXPECT_EQ(m.type, "homogeneous");
  EXPECT_FALSE(m.params.Has("type"));
  m.params.GetOneRGB("sigma_a", SpectrumType::kUnbounded);
  try {
    m.params.ReportUnused("MakeNamedMedium \"homogeneous\"");
    ADD_FAILURE() << "expected an unused-parameter error";
  } catch (const SceneError& e) {
    EXPECT_STREQ(
        e.what(),
        "test.pbrt:5: unused parameter \"float sigmaa\" in MakeNamedMedium \"homogeneous\"");
  }
}

TEST_F(ParserTest, BlockStructureRules) {
  ExpectError("Material \"diffuse\"\nWorldBegin\n", 1, "only allowed after WorldBegin");
  ExpectError("MakeNamedMaterial \"m\" \"string type\" \"diffuse\"\n", 1,
              "only allowed after WorldBegin");
  ExpectError("WorldBegin\nCamera \"perspective\"\n", 2, "must come before WorldBegin");
  ExpectError("WorldBegin\nWorldBegin\n", 2, "WorldBegin appears twice");
  ExpectError("Camera \"perspective\"\n", 1, "end of file before WorldBegin");
  ExpectError(
      "WorldBegin\nMakeNamedMaterial \"m\" \"string type\" \"diffuse\"\n"
      "MakeNamedMaterial \"m\" \"string type\" \"diffuse\"\n",
      3, "redefined");
  ExpectError("WorldBegin\nMakeNamedMaterial \"m\" \"rgb reflectance\" [ 1 1 1 ]\n", 2,
              "no \"string type\"");
}

TEST_F(ParserTest, UnsupportedFeatures) {
  ExpectError("ActiveTransform StartTime\nWorldBegin\n", 1,
              "motion blur (ActiveTransform) is not supported");
  ExpectError("TransformTimes 0 2\nWorldBegin\n", 1, "motion blur");
  EXPECT_NO_THROW(Parse("ActiveTransform All\nTransformTimes 0 1\nWorldBegin\n"));
  ExpectError("ColorSpace \"aces2065-1\"\nWorldBegin\n", 1,
              "unsupported color space \"aces2065-1\"");
  EXPECT_NO_THROW(Parse("ColorSpace \"srgb\"\nWorldBegin\n"));
  EXPECT_NO_THROW(Parse("Option \"disablepixeljitter\" true\nOption \"seed\" 7\nWorldBegin\n"));
  ExpectError("\nOption \"frobnicate\" true\nWorldBegin\n", 2, "unknown Option \"frobnicate\"");
  ExpectError("Option \"disablepixeljitter\" 3\nWorldBegin\n", 1, "true or false");
  ExpectError(
      "WorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\"\nObjectBegin \"o\"\n"
      "Shape \"sphere\"\n",
      5, "instanced area lights are not supported");
}

// --- Transforms ------------------------------------------------------------------------------

TEST_F(ParserTest, TransformsComposeAsInPbrt) {
  SceneDescription s = Parse(
      "WorldBegin\n"
      "Translate 1 2 3\nShape \"sphere\"\n"                                               // 0
      "Identity\nScale 2 3 4\nTranslate 1 1 1\nShape \"sphere\"\n"                        // 1
      "Identity\nRotate 90 0 0 1\nShape \"sphere\"\n"                                     // 2
      "Transform [ 1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1 ]\nShape \"sphere\"\n"              // 3
      "Identity\nTranslate 1 0 0\nConcatTransform [ 2 0 0 0 0 2 0 0 0 0 2 0 0 0 0 1 ]\n"  // 4
      "Shape \"sphere\"\n");
  ASSERT_EQ(s.shapes.size(), 5u);
  ExpectNear(s.shapes[0].world_from_object.ApplyPoint({0, 0, 0}), {1, 2, 3});
  // Later transforms apply first: Scale(Translate(p)).
  ExpectNear(s.shapes[1].world_from_object.ApplyPoint({0, 0, 0}), {2, 3, 4});
  ExpectNear(s.shapes[2].world_from_object.ApplyPoint({1, 0, 0}), {0, 1, 0});
  ExpectNear(s.shapes[3].world_from_object.ApplyPoint({1, 1, 1}), {6, 7, 8});
  ExpectNear(s.shapes[4].world_from_object.ApplyPoint({1, 1, 1}), {3, 2, 2});
}

TEST_F(ParserTest, LookAtCameraAndNamedCoordinateSystems) {
  SceneDescription s = Parse(
      "LookAt 0 0 5  0 0 0  0 1 0\n"
      "Camera \"perspective\" \"float fov\" 30\n"
      "WorldBegin\n"
      "Translate 9 9 9\n"
      "CoordSysTransform \"camera\"\nShape \"sphere\"\n"
      "CoordinateSystem \"mine\"\nIdentity\nCoordSysTransform \"world\"\nShape \"sphere\"\n"
      "CoordSysTransform \"mine\"\nShape \"sphere\"\n");
  EXPECT_TRUE(s.has_camera);
  // pbrt cameras look down +z: the world origin is 5 units in front of the eye.
  ExpectNear(s.camera.camera_from_world.ApplyPoint({0, 0, 0}), {0, 0, 5});
  ExpectNear(s.camera.camera_from_world.ApplyPoint({0, 0, 5}), {0, 0, 0});
  ASSERT_EQ(s.shapes.size(), 3u);
  ExpectNear(s.shapes[0].world_from_object.ApplyPoint({0, 0, 0}), {0, 0, 5});  // the eye
  ExpectNear(s.shapes[1].world_from_object.ApplyPoint({1, 2, 3}), {1, 2, 3});
  ExpectNear(s.shapes[2].world_from_object.ApplyPoint({0, 0, 0}), {0, 0, 5});
  ExpectError("WorldBegin\nCoordSysTransform \"nowhere\"\n", 2, "unknown coordinate system");
  ExpectError("LookAt 0 0 0 0 0 0 0 1 0\nWorldBegin\n", 1, "degenerate");
}

TEST_F(ParserTest, WorldBeginResetsTransform) {
  SceneDescription s =
      Parse("Scale -1 1 1\nCamera \"perspective\"\nWorldBegin\nShape \"sphere\"\n");
  EXPECT_TRUE(s.shapes[0].world_from_object.IsIdentity());
  EXPECT_FALSE(s.camera.camera_from_world.IsIdentity());
}

// --- Graphics state --------------------------------------------------------------------------

TEST_F(ParserTest, AttributeStackRestoresState) {
  SceneDescription s = Parse(
      "WorldBegin\n"
      "Material \"diffuse\"\n"
      "AttributeBegin\n"
      "  Translate 1 0 0\n  ReverseOrientation\n  Material \"conductor\"\n"
      "  AreaLightSource \"diffuse\" \"rgb L\" [ 1 1 1 ]\n"
      "  Shape \"sphere\"\n"
      "AttributeEnd\n"
      "Shape \"sphere\"\n"
      "TransformBegin\n  Translate 0 5 0\n  Material \"dielectric\"\nTransformEnd\n"
      "Shape \"sphere\"\n");
  ASSERT_EQ(s.shapes.size(), 3u);
  ASSERT_EQ(s.materials.size(), 3u);
  const ShapeDesc &inside = s.shapes[0], &after = s.shapes[1], &after_transform = s.shapes[2];
  EXPECT_EQ(s.materials[inside.material].type, "conductor");
  EXPECT_TRUE(inside.reverse_orientation);
  EXPECT_TRUE(inside.area_light.has_value());
  ExpectNear(inside.world_from_object.ApplyPoint({0, 0, 0}), {1, 0, 0});
  EXPECT_EQ(s.materials[after.material].type, "diffuse");
  EXPECT_FALSE(after.reverse_orientation);
  EXPECT_FALSE(after.area_light.has_value());
  EXPECT_TRUE(after.world_from_object.IsIdentity());
  // TransformEnd restores the CTM only; the material set inside stays.
  EXPECT_TRUE(after_transform.world_from_object.IsIdentity());
  EXPECT_EQ(s.materials[after_transform.material].type, "dielectric");
}

TEST_F(ParserTest, NamedAndDefaultMaterials) {
  SceneDescription s = Parse(
      "WorldBegin\n"
      "Shape \"sphere\"\n"
      "MakeNamedMaterial \"red\" \"string type\" \"diffuse\" \"rgb reflectance\" [ 0.8 0.1 0.1 ]\n"
      "Shape \"sphere\"\n"  // MakeNamedMaterial does not change the current material
      "NamedMaterial \"red\"\nShape \"sphere\"\n"
      "Material \"conductor\"\nShape \"sphere\"\n");
  ASSERT_EQ(s.shapes.size(), 4u);
  EXPECT_EQ(s.shapes[0].material, -1);
  EXPECT_EQ(s.shapes[1].material, -1);
  int red = s.named_materials.at("red");
  EXPECT_EQ(s.shapes[2].material, red);
  const MaterialDesc& m = s.materials[red];
  EXPECT_EQ(m.name, "red");
  EXPECT_EQ(m.type, "diffuse");
  EXPECT_FALSE(m.params.Has("type"));
  RGB r = *m.params.GetOneRGB("reflectance", SpectrumType::kAlbedo);
  EXPECT_FLOAT_EQ(r.r, 0.8f);
  EXPECT_NO_THROW(m.params.ReportUnused("MakeNamedMaterial \"red\""));
  EXPECT_EQ(s.materials[s.shapes[3].material].name, "");
  EXPECT_EQ(s.materials[s.shapes[3].material].type, "conductor");
}

TEST_F(ParserTest, AreaLightAppliesOnlyInItsScope) {
  SceneDescription s = Parse(
      "WorldBegin\n"
      "Shape \"sphere\"\n"
      "AttributeBegin\n"
      "  AreaLightSource \"diffuse\" \"blackbody L\" 6500\n"
      "  Shape \"sphere\"\n"
      "  AttributeBegin\n    Shape \"disk\"\n  AttributeEnd\n"
      "AttributeEnd\n"
      "Shape \"sphere\"\n");
  ASSERT_EQ(s.shapes.size(), 4u);
  EXPECT_FALSE(s.shapes[0].area_light);
  ASSERT_TRUE(s.shapes[1].area_light);
  EXPECT_EQ(s.shapes[1].area_light->type, "diffuse");
  EXPECT_EQ(s.shapes[1].area_light->loc.line, 4);
  EXPECT_TRUE(s.shapes[2].area_light);
  EXPECT_FALSE(s.shapes[3].area_light);
  RGB l = *s.shapes[1].area_light->params.GetOneRGB("L", SpectrumType::kIlluminant);
  EXPECT_FLOAT_EQ(l.Max(), 1.f);
}

TEST_F(ParserTest, ObjectInstancing) {
  SceneDescription s = Parse(
      "WorldBegin\n"
      "ObjectBegin \"tree\"\n"
      "  Translate 0 1 0\n  Shape \"sphere\"\n  Shape \"cylinder\"\n"
      "ObjectEnd\n"
      "Shape \"disk\"\n"  // the CTM set inside the object is gone
      "Translate 10 0 0\nObjectInstance \"tree\"\n"
      "Translate 10 0 0\nObjectInstance \"tree\"\n");
  ASSERT_EQ(s.shapes.size(), 1u);
  EXPECT_TRUE(s.shapes[0].world_from_object.IsIdentity());
  ASSERT_EQ(s.instance_definitions.at("tree").size(), 2u);
  ExpectNear(s.instance_definitions.at("tree")[0].world_from_object.ApplyPoint({0, 0, 0}),
             {0, 1, 0});
  ASSERT_EQ(s.instance_uses.size(), 2u);
  EXPECT_EQ(s.instance_uses[1].name, "tree");
  EXPECT_EQ(s.instance_uses[1].loc.line, 11);
  ExpectNear(s.instance_uses[1].world_from_instance.ApplyPoint({0, 0, 0}), {20, 0, 0});
  ExpectError("WorldBegin\nObjectBegin \"a\"\nObjectEnd\nObjectBegin \"a\"\n", 4, "redefined");
}

TEST_F(ParserTest, AttributeDefaults) {
  SceneDescription s = Parse(
      "WorldBegin\n"
      "AttributeBegin\n"
      "  Attribute \"shape\" \"float radius\" 2\n"
      "  Shape \"sphere\"\n"
      "  Shape \"sphere\" \"float radius\" 3\n"
      "  Shape \"trianglemesh\" \"point3 P\" [ 0 0 0 1 0 0 0 1 0 ] \"integer indices\" [ 0 1 2 ]\n"
      "AttributeEnd\n"
      "Shape \"sphere\"\n");
  ASSERT_EQ(s.shapes.size(), 4u);
  EXPECT_EQ(s.shapes[0].params.GetOneFloat("radius", 1), 2.f);
  EXPECT_EQ(s.shapes[1].params.GetOneFloat("radius", 1), 3.f);
  // A default the shape does not take is not an unused parameter.
  s.shapes[2].params.GetPoint3Array("P");
  s.shapes[2].params.GetIntArray("indices");
  EXPECT_NO_THROW(s.shapes[2].params.ReportUnused("Shape \"trianglemesh\""));
  EXPECT_EQ(s.shapes[3].params.GetOneFloat("radius", 1), 1.f);
  ExpectError("WorldBegin\nAttribute \"camera\" \"float fov\" 3\n", 2, "unknown Attribute target");
}

TEST_F(ParserTest, MediaAndInterfaces) {
  SceneDescription s = Parse(
      "MakeNamedMedium \"air\" \"string type\" \"homogeneous\"\n"
      "MediumInterface \"air\"\n"
      "Camera \"perspective\"\n"
      "WorldBegin\n"
      "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_s\" [ 1 1 1 ]\n"
      "AttributeBegin\n  MediumInterface \"fog\" \"air\"\n  Shape \"sphere\"\nAttributeEnd\n"
      "LightSource \"point\"\n"
      "MediumInterface \"\" \"\"\nShape \"sphere\"\n");
  EXPECT_EQ(s.camera.medium, "air");
  ASSERT_EQ(s.shapes.size(), 2u);
  EXPECT_EQ(s.shapes[0].inside_medium, "fog");
  EXPECT_EQ(s.shapes[0].outside_medium, "air");
  ASSERT_EQ(s.lights.size(), 1u);
  EXPECT_EQ(s.lights[0].medium, "air");  // the interface set before WorldBegin
  EXPECT_EQ(s.shapes[1].inside_medium, "");
  EXPECT_EQ(s.shapes[1].outside_medium, "");
  EXPECT_EQ(s.media.at("fog").type, "homogeneous");
  EXPECT_EQ(s.media.size(), 2u);
}

TEST_F(ParserTest, IncludeAndImport) {
  Write("parts/materials.pbrt",
        "MakeNamedMaterial \"white\" \"string type\" \"diffuse\"\n"
        "# relative to the root file's directory, as in pbrt-v4\n"
        "Include \"parts/shapes.pbrt\"\n");
  Write("parts/shapes.pbrt", "Shape \"plymesh\" \"string filename\" \"models/a.ply\"\n");
  Write("imported.pbrt", "Translate 100 0 0\nNamedMaterial \"white\"\nShape \"sphere\"\n");
  std::string root =
      Write("scene.pbrt",
            "Film \"rgb\" \"string filename\" \"out.exr\"\n"
            "WorldBegin\n"
            "Include \"parts/materials.pbrt\"\n"
            "Import \"imported.pbrt\"\n"
            "Shape \"sphere\"\n"
            "Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"tex.png\"\n");
  SceneDescription s = ParseSceneFile(root);
  EXPECT_EQ(s.root_file, root);
  EXPECT_EQ(s.base_dir, dir_.string());
  std::vector<std::string> expected_files = {root,
                                             (dir_ / "parts/materials.pbrt").string(),
                                             (dir_ / "parts/shapes.pbrt").string(),
                                             (dir_ / "models/a.ply").string(),
                                             (dir_ / "imported.pbrt").string(),
                                             (dir_ / "tex.png").string()};
  EXPECT_EQ(s.files, expected_files);  // the film's output file is not an input
  ASSERT_EQ(s.shapes.size(), 3u);
  EXPECT_EQ(s.shapes[0].type, "plymesh");
  EXPECT_EQ(s.shapes[0].params.GetOneString("filename", ""), "models/a.ply");
  // The imported file's Translate and NamedMaterial do not leak into the importer.
  ExpectNear(s.shapes[1].world_from_object.ApplyPoint({0, 0, 0}), {100, 0, 0});
  EXPECT_EQ(s.shapes[1].material, s.named_materials.at("white"));
  EXPECT_TRUE(s.shapes[2].world_from_object.IsIdentity());
  EXPECT_EQ(s.shapes[2].material, -1);
  EXPECT_EQ(s.textures.at("t").value_type, "spectrum");
  EXPECT_EQ(s.ResolvePath("/abs/x.ply"), "/abs/x.ply");
  EXPECT_EQ(s.ResolvePath("x.ply"), (dir_ / "x.ply").string());

  // Errors inside an included file name that file.
  std::string bad = Write("bad.pbrt", "\n\nShape \"sphere\" \"float radius\" [ 1 2 ] oops\n");
  ExpectErrorIn([&] { Parse("WorldBegin\nInclude \"bad.pbrt\"\n"); },
                bad + ":3:", "unknown directive \"oops\"");
  Write("open.pbrt", "AttributeBegin\n");
  ExpectErrorIn([&] { Parse("WorldBegin\nImport \"open.pbrt\"\n"); }, dir_.string(),
                "never closed in the imported file");
}

TEST_F(ParserTest, HostileInputNeverCrashes) {
  // Random edits of a valid scene must end in success or a SceneError, nothing else.
  const std::string base =
      "LookAt 0 0 5 0 0 0 0 1 0\nCamera \"perspective\" \"float fov\" [ 45 ]\n"
      "Film \"rgb\" \"integer xresolution\" 64\nWorldBegin\n"
      "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [ 1 2 3 ]\n"
      "  Shape \"trianglemesh\" \"point3 P\" [ 0 0 0 1 0 0 0 1 0 ] \"integer indices\" [ 0 1 2 ]\n"
      "AttributeEnd\nMakeNamedMaterial \"m\" \"string type\" \"diffuse\"\nNamedMaterial \"m\"\n"
      "ObjectBegin \"o\"\nShape \"sphere\" \"bool b\" true\nObjectEnd\nObjectInstance \"o\"\n";
  const std::string alphabet = "\"[]#\n \\0123456789.e-+AWS";
  std::mt19937 rng(12345);
  int errors = 0;
  for (int iter = 0; iter < 3000; ++iter) {
    std::string text = base;
    int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      size_t pos = rng() % text.size();
      switch (rng() % 3) {
        case 0:
          text.erase(pos, 1 + rng() % 8);
          break;
        case 1:
          text.insert(pos, 1, alphabet[rng() % alphabet.size()]);
          break;
        default:
          text[pos] = static_cast<char>(rng() % 256);
          break;
      }
      if (text.empty()) text = " ";
    }
    try {
      Parse(text);
    } catch (const SceneError&) {
      ++errors;
    }
  }
  EXPECT_GT(errors, 100);  // the edits do break things, and each break is a SceneError
}

// --- ParamSet --------------------------------------------------------------------------------

Param MakeParam(std::string type, std::string name, std::vector<double> numbers, int line = 7) {
  Param p;
  p.type = std::move(type);
  p.name = std::move(name);
  p.numbers = std::move(numbers);
  p.loc = FileLoc{"p.pbrt", line, 1};
  return p;
}

TEST(ParamSetTest, TypeChecksAndSynonyms) {
  ParamSet ps;
  ps.Add(MakeParam("point", "P", {0, 1, 2, 3, 4, 5}));
  ps.Add(MakeParam("normal", "N", {0, 0, 1}));
  ps.Add(MakeParam("vector", "up", {0, 1, 0}));
  ps.Add(MakeParam("color", "Kd", {0.1, 0.2, 0.3}));
  ps.Add(MakeParam("integer", "n", {4}));
  ps.Add(MakeParam("float", "f", {2.5}));
  EXPECT_EQ(ps.GetPoint3Array("P").size(), 2u);
  EXPECT_EQ(ps.GetNormalArray("N")[0].z, 1.f);
  EXPECT_EQ(ps.GetOneVector3("up")->y, 1.f);
  EXPECT_FLOAT_EQ(ps.GetOneRGB("Kd", SpectrumType::kAlbedo)->g, 0.2f);
  EXPECT_EQ(ps.GetOneInt("n", 0), 4);
  EXPECT_EQ(ps.GetOneInt("missing", 9), 9);
  // GetOneFloat takes "float" only, GetOneInt "integer" only.
  try {
    ps.GetOneFloat("n", 0);
    ADD_FAILURE();
  } catch (const SceneError& e) {
    EXPECT_STREQ(e.what(), "p.pbrt:7: parameter \"n\" is integer, expected float");
  }
  EXPECT_THROW(ps.GetOneInt("f", 0), SceneError);
  EXPECT_THROW(ps.GetOnePoint3("up"), SceneError);
}

TEST(ParamSetTest, UsedMarkingAndReportUnused) {
  ParamSet ps;
  ps.Add(MakeParam("float", "a", {1}, 3));
  ps.Add(MakeParam("float", "b", {2}, 4));
  EXPECT_TRUE(ps.Has("a"));
  EXPECT_FALSE(ps.Find("a")->used);  // Has/Find do not count as use
  ps.GetOneFloat("a", 0);
  EXPECT_TRUE(ps.Find("a")->used);
  try {
    ps.ReportUnused("Shape \"sphere\"");
    ADD_FAILURE();
  } catch (const SceneError& e) {
    EXPECT_STREQ(e.what(), "p.pbrt:4: unused parameter \"float b\" in Shape \"sphere\"");
  }
  ps.GetFloatArray("b");
  EXPECT_NO_THROW(ps.ReportUnused("Shape \"sphere\""));
}

TEST(ParamSetTest, AddReplacesAndDefaultsFillIn) {
  ParamSet ps;
  ps.Add(MakeParam("float", "radius", {1}));
  ps.Add(MakeParam("float", "radius", {2}));
  EXPECT_EQ(ps.params().size(), 1u);
  ParamSet defaults;
  defaults.Add(MakeParam("float", "radius", {5}));
  defaults.Add(MakeParam("float", "zmax", {6}));
  ps.AddDefaults(defaults);
  EXPECT_EQ(ps.GetOneFloat("radius", 0), 2.f);
  EXPECT_EQ(ps.GetOneFloat("zmax", 0), 6.f);
  ParamSet only_defaults;
  only_defaults.AddDefaults(defaults);
  EXPECT_NO_THROW(only_defaults.ReportUnused("Shape"));
}

TEST(ParamSetTest, ValueCountsAreChecked) {
  ParamSet ps;
  ps.Add(MakeParam("rgb", "L", {1, 2}, 12));
  ps.Add(MakeParam("float", "two", {1, 2}));
  ps.Add(MakeParam("point3", "P", {1, 2, 3, 4}));
  try {
    ps.GetOneRGB("L", SpectrumType::kIlluminant);
    ADD_FAILURE();
  } catch (const SceneError& e) {
    EXPECT_EQ(e.loc().line, 12);
    EXPECT_NE(std::string(e.what()).find("needs exactly 3 numbers"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ps.GetOneFloat("two", 0), SceneError);
  EXPECT_EQ(ps.GetFloatArray("two").size(), 2u);
  EXPECT_THROW(ps.GetPoint3Array("P"), SceneError);
}

TEST(ParamSetTest, SpectraAsRGB) {
  ParamSet ps;
  ps.Add(MakeParam("rgb", "bright", {1.5, 0.5, 0.5}));
  ps.Add(MakeParam("rgb", "negative", {-0.1, 0.5, 0.5}));
  ps.Add(MakeParam("float", "eta", {1.5}));
  ps.Add(MakeParam("blackbody", "L", {3000}));
  ps.Add(MakeParam("spectrum", "flat", {400, 0.25, 700, 0.25}));
  ps.Add(MakeParam("spectrum", "backwards", {700, 0.25, 400, 0.25}));
  Param named = MakeParam("spectrum", "k", {});
  named.strings = {"metal-Cu-k"};
  ps.Add(named);
  Param unknown = MakeParam("spectrum", "what", {});
  unknown.strings = {"metal-Unobtainium-k"};
  ps.Add(unknown);

  EXPECT_THROW(ps.GetOneRGB("bright", SpectrumType::kAlbedo), SceneError);
  EXPECT_FLOAT_EQ(ps.GetOneRGB("bright", SpectrumType::kIlluminant)->r, 1.5f);
  EXPECT_THROW(ps.GetOneRGB("negative", SpectrumType::kUnbounded), SceneError);
  EXPECT_EQ(*ps.GetOneRGB("eta", SpectrumType::kUnbounded), RGB(1.5f));
  RGB bb = *ps.GetOneRGB("L", SpectrumType::kIlluminant);
  EXPECT_FLOAT_EQ(bb.Max(), 1.f);
  EXPECT_GT(bb.r, bb.b);  // 3000 K is warm
  RGB flat = *ps.GetOneRGB("flat", SpectrumType::kAlbedo);
  EXPECT_NEAR(flat.r, 0.25f, 1e-3f);
  EXPECT_NEAR(flat.b, 0.25f, 1e-3f);
  EXPECT_THROW(ps.GetOneRGB("backwards", SpectrumType::kAlbedo), SceneError);
  EXPECT_EQ(*ps.GetOneRGB("k", SpectrumType::kUnbounded), *NamedSpectrumToRGB("metal-Cu-k"));
  EXPECT_THROW(ps.GetOneRGB("what", SpectrumType::kUnbounded), SceneError);
  EXPECT_FALSE(ps.GetOneRGB("absent", SpectrumType::kAlbedo).has_value());
}

TEST(ParamSetTest, TexturesAndStrings) {
  ParamSet ps;
  Param tex = MakeParam("texture", "reflectance", {});
  tex.strings = {"checks"};
  ps.Add(tex);
  Param b;
  b.type = "bool";
  b.name = "flip";
  b.bools = {true};
  ps.Add(b);
  EXPECT_EQ(ps.GetTexture("reflectance"), "checks");
  EXPECT_EQ(ps.GetTexture("absent"), "");
  EXPECT_TRUE(ps.GetOneBool("flip", false));
  EXPECT_THROW(ps.GetOneString("reflectance", ""), SceneError);
}

// --- Spectra ---------------------------------------------------------------------------------

TEST(SpectrumTest, BlackbodyColours) {
  RGB d65ish = BlackbodyToRGB(6500.f);
  EXPECT_FLOAT_EQ(d65ish.Max(), 1.f);
  EXPECT_GT(d65ish.r, 0.8f);
  EXPECT_GT(d65ish.g, 0.8f);
  EXPECT_GT(d65ish.b, 0.8f);
  RGB warm = BlackbodyToRGB(2700.f);
  EXPECT_GT(warm.r, warm.g);
  EXPECT_GT(warm.g, warm.b);
  RGB hot = BlackbodyToRGB(20000.f);
  EXPECT_GT(hot.b, hot.r);
  EXPECT_EQ(BlackbodyToRGB(0.f), RGB(0.f));
  RGB very_red = BlackbodyToRGB(800.f);  // outside the gamut: clipped, never negative
  EXPECT_GE(very_red.b, 0.f);
  EXPECT_FLOAT_EQ(very_red.r, 1.f);
}

TEST(SpectrumTest, SampledSpectra) {
  RGB half = SampledSpectrumToRGB({360, 0.5, 830, 0.5}, SpectrumType::kAlbedo);
  EXPECT_NEAR(half.r, 0.5f, 1e-2f);
  EXPECT_NEAR(half.g, 0.5f, 1e-2f);
  EXPECT_NEAR(half.b, 0.5f, 1e-2f);
  RGB one = SampledSpectrumToRGB({300, 1, 900, 1}, SpectrumType::kIlluminant);
  EXPECT_NEAR(one.r, 1.f, 1e-3f);
  EXPECT_NEAR(one.g, 1.f, 1e-3f);
  EXPECT_NEAR(one.b, 1.f, 1e-3f);
  // Energy only above 600 nm is red; only below 480 nm is blue.
  RGB red = SampledSpectrumToRGB({590, 0, 600, 1, 830, 1}, SpectrumType::kUnbounded);
  EXPECT_GT(red.r, 5 * std::abs(red.g));
  EXPECT_GT(red.r, 5 * std::abs(red.b));
  RGB blue = SampledSpectrumToRGB({360, 1, 470, 1, 480, 0}, SpectrumType::kUnbounded);
  EXPECT_GT(blue.b, blue.r);
  EXPECT_GT(blue.b, blue.g);
}

TEST(SpectrumTest, NamedSpectra) {
  EXPECT_EQ(*NamedSpectrumToRGB("metal-Cu-eta"), RGB(0.200438f, 0.924033f, 1.102212f));
  EXPECT_EQ(*NamedSpectrumToRGB("metal-Cu-k"), RGB(3.912949f, 2.452848f, 2.142188f));
  for (const char* name : {"metal-Au-eta", "metal-Au-k", "metal-Ag-eta", "metal-Ag-k",
                           "metal-Al-eta", "metal-Al-k", "metal-CuZn-eta", "metal-CuZn-k"})
    EXPECT_TRUE(NamedSpectrumToRGB(name).has_value()) << name;
  RGB bk7 = *NamedSpectrumToRGB("glass-BK7");
  EXPECT_NEAR(bk7.g, 1.5185f, 1e-3f);
  EXPECT_EQ(bk7.r, bk7.b);
  EXPECT_GT(NamedSpectrumToRGB("glass-F11")->g, NamedSpectrumToRGB("glass-F5")->g);
  EXPECT_EQ(*NamedSpectrumToRGB("stdillum-D65"), RGB(1.f));
  EXPECT_FALSE(NamedSpectrumToRGB("metal-Unobtainium-eta").has_value());
}

// --- The shared scenes -----------------------------------------------------------------------

std::string SharedScene(const std::string& name) {
  const char* env = std::getenv("LIGHTFARM_SHARED");
  fs::path shared = env && *env ? fs::path(env) : fs::path(LIGHTFARM_SOURCE_DIR) / ".." / "shared";
  return (shared / "scenes" / name / "scene.pbrt").lexically_normal().string();
}

// Parses a shared scene; a missing scene is a failure, never a skip.
SceneDescription ParseShared(const std::string& name) {
  std::string path = SharedScene(name);
  if (!fs::is_regular_file(path))
    throw std::runtime_error("shared scene " + path +
                             " not found; set LIGHTFARM_SHARED to the shared directory");
  return ParseSceneFile(path);
}

int CountAreaLights(const SceneDescription& s) {
  int n = 0;
  for (const ShapeDesc& shape : s.shapes) n += shape.area_light.has_value();
  return n;
}

TEST(SharedScenesTest, CornellBox) {
  SceneDescription s = ParseShared("cornell-box");
  EXPECT_EQ(s.shapes.size(), 8u);
  EXPECT_EQ(CountAreaLights(s), 1);
  EXPECT_EQ(s.named_materials.size(), 8u);
  EXPECT_TRUE(s.has_camera);
  EXPECT_EQ(s.camera.type, "perspective");
  EXPECT_FLOAT_EQ(s.camera.params.GetOneFloat("fov", 90), 19.5f);
  EXPECT_EQ(s.film.params.GetOneInt("xresolution", 0), 1024);
  EXPECT_EQ(s.film.params.GetOneInt("yresolution", 0), 1024);
  EXPECT_EQ(s.integrator.type, "path");
  EXPECT_EQ(s.integrator.params.GetOneInt("maxdepth", 0), 65);
  EXPECT_EQ(s.sampler.params.GetOneInt("pixelsamples", 0), 512);
  EXPECT_EQ(s.files, std::vector<std::string>{s.root_file});
  // Transform [ 1 0 0 0  0 1 0 0  0 0 -1 0  0 -1 6.8 1 ]: the eye sits at (0, 1, 6.8).
  ExpectNear(s.camera.camera_from_world.Inverse()->ApplyPoint({0, 0, 0}), {0, 1, 6.8f}, 1e-4f);
  for (const ShapeDesc& shape : s.shapes) {
    EXPECT_GE(shape.material, 0);
    EXPECT_EQ(shape.type, "trianglemesh");
    EXPECT_EQ(shape.params.GetPoint3Array("P").size() % 4, 0u);
  }
  const ShapeDesc& light = s.shapes.back();
  ASSERT_TRUE(light.area_light);
  EXPECT_EQ(*light.area_light->params.GetOneRGB("L", SpectrumType::kIlluminant), RGB(17, 12, 4));
  EXPECT_EQ(s.materials[light.material].name, "Light");
}

TEST(SharedScenesTest, VeachMis) {
  SceneDescription s = ParseShared("veach-mis");
  EXPECT_EQ(s.shapes.size(), 9u);
  EXPECT_EQ(CountAreaLights(s), 3);
  EXPECT_EQ(s.named_materials.size(), 6u);
  EXPECT_NEAR(s.camera.params.GetOneFloat("fov", 0), 20.114292f, 1e-5f);
  EXPECT_EQ(s.film.params.GetOneInt("xresolution", 0), 1280);
  EXPECT_EQ(s.film.params.GetOneInt("yresolution", 0), 720);
  const MaterialDesc& smooth = s.materials[s.named_materials.at("Smooth")];
  EXPECT_EQ(smooth.type, "conductor");
  // The scene writes copper's RGB constants: the same as the named spectrum table.
  EXPECT_EQ(*smooth.params.GetOneRGB("eta", SpectrumType::kUnbounded),
            *NamedSpectrumToRGB("metal-Cu-eta"));
  EXPECT_FALSE(smooth.params.GetOneBool("remaproughness", true));
  int spheres = 0;
  for (const ShapeDesc& shape : s.shapes) {
    if (shape.type != "sphere") continue;
    ++spheres;
    EXPECT_TRUE(shape.area_light);
    EXPECT_NEAR(shape.world_from_object.ApplyPoint({0, 0, 0}).y, 6.5f, 1e-5f);
  }
  EXPECT_EQ(spheres, 3);
}

TEST(SharedScenesTest, WaterCaustic) {
  SceneDescription s = ParseShared("water-caustic");
  EXPECT_EQ(s.shapes.size(), 10u);
  EXPECT_EQ(CountAreaLights(s), 1);
  EXPECT_EQ(s.named_materials.size(), 9u);
  EXPECT_EQ(s.integrator.type, "sppm");
  int plymeshes = 0;
  for (const ShapeDesc& shape : s.shapes) {
    if (shape.type != "plymesh") continue;
    ++plymeshes;
    EXPECT_EQ(s.materials[shape.material].name, "Water");
    ExpectNear(shape.world_from_object.ApplyPoint({1, 1, 1}), {1, 1.5f, 1});
  }
  EXPECT_EQ(plymeshes, 2);
  // Root first, then the two PLY files, which exist.
  ASSERT_EQ(s.files.size(), 3u);
  EXPECT_EQ(s.files[0], s.root_file);
  EXPECT_EQ(fs::path(s.files[1]).filename(), "Mesh001.ply");
  EXPECT_EQ(fs::path(s.files[2]).filename(), "Mesh000.ply");
  for (const std::string& f : s.files) EXPECT_TRUE(fs::is_regular_file(f)) << f;
}

TEST(SharedScenesTest, VolumetricCaustic) {
  SceneDescription s = ParseShared("volumetric-caustic");
  EXPECT_EQ(s.shapes.size(), 8u);
  EXPECT_EQ(CountAreaLights(s), 1);
  EXPECT_EQ(s.integrator.type, "volpath");
  ASSERT_EQ(s.media.size(), 1u);
  const MediumDesc& gas = s.media.at("gas");
  EXPECT_EQ(gas.type, "homogeneous");
  EXPECT_EQ(*gas.params.GetOneRGB("sigma_s", SpectrumType::kUnbounded), RGB(1.f));
  EXPECT_EQ(*gas.params.GetOneRGB("sigma_a", SpectrumType::kUnbounded), RGB(0.f));
  EXPECT_EQ(gas.params.GetOneFloat("scale", 0), 1.f);
  EXPECT_NO_THROW(gas.params.ReportUnused("MakeNamedMedium \"gas\""));
  EXPECT_EQ(s.camera.medium, "");
  int inside_gas = 0, outside_gas = 0;
  for (const ShapeDesc& shape : s.shapes) {
    inside_gas += shape.inside_medium == "gas";
    outside_gas += shape.outside_medium == "gas";
  }
  EXPECT_EQ(inside_gas, 1);   // the front wall: MediumInterface "gas" ""
  EXPECT_EQ(outside_gas, 2);  // the glass sphere and the light
  const MaterialDesc& sphere = s.materials[s.named_materials.at("Sphere")];
  EXPECT_EQ(*sphere.params.GetOneRGB("eta", SpectrumType::kUnbounded), RGB(1.5f));
}

}  // namespace test_parser
}  // namespace lightfarm
