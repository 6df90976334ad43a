// Tests for common/image: EXR/PNG I/O, resizing, error metrics and heatmaps, pixel filters and
// filter importance sampling, and the film.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/image/film.h"
#include "common/image/filter.h"
#include "common/image/image.h"
#include "common/image/image_io.h"
#include "common/image/metrics.h"
#include "common/util/error.h"
#include "common/util/rng.h"

namespace lightfarm {
namespace test_image {

namespace fs = std::filesystem;

// A fresh directory per test, removed afterwards.
class ScratchDir {
 public:
  ScratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() / ("lightfarm_image_" + std::string(info->test_suite_name()) +
                                         "_" + info->name() + "_" + std::to_string(::getpid()));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  std::string File(const std::string& name) const { return (path_ / name).string(); }
  // Names of everything in the directory, to catch left-over temporary files.
  std::vector<std::string> Listing() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(path_)) {
      names.push_back(entry.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
  }

 private:
  fs::path path_;
};

Image RandomImage(int w, int h, uint64_t seed, float scale = 1.f) {
  Rng rng(seed);
  Image image(w, h);
  for (RGB& p : image.pixels) p = RGB(rng.Uniform(), rng.Uniform(), rng.Uniform()) * scale;
  return image;
}

double MeanChannel(const Image& image) {
  double sum = 0;
  for (const RGB& p : image.pixels) sum += double(p.r) + double(p.g) + double(p.b);
  return sum / (3.0 * double(image.PixelCount()));
}

// Reads an 8-bit image's raw bytes, independently of ReadImage.
std::vector<uint8_t> ReadBytes(const std::string& path, int* width, int* height) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw std::runtime_error(OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  *width = spec.width;
  *height = spec.height;
  std::vector<uint8_t> bytes(size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, bytes.data())) {
    throw std::runtime_error(in->geterror());
  }
  return bytes;
}

// --- Image I/O ------------------------------------------------------------------------------

TEST(ImageIO, ExrRoundTripIsBitExact) {
  ScratchDir dir;
  Image image = RandomImage(37, 19, 1, 1000.f);
  // Values float formats find awkward: negatives, denormals, huge and tiny magnitudes.
  image.at(0, 0) = RGB(-3.5f, 1e-40f, 3e38f);
  image.at(36, 18) = RGB(0.f, 1.f / 3.f, 6.1e-5f);
  const std::string path = dir.File("round_trip.exr");
  WriteEXR(path, image);

  const Image back = ReadImage(path);
  ASSERT_EQ(back.width, 37);
  ASSERT_EQ(back.height, 19);
  ASSERT_EQ(back.PixelCount(), image.PixelCount());
  EXPECT_EQ(std::memcmp(back.pixels.data(), image.pixels.data(), image.PixelCount() * sizeof(RGB)),
            0);
  EXPECT_EQ(back.at(0, 0).r, -3.5f);
  EXPECT_EQ(back.at(36, 18).g, 1.f / 3.f);

  // Float RGB with zip compression, and no temporary file left beside it.
  auto in = OIIO::ImageInput::open(path);
  ASSERT_TRUE(in) << OIIO::geterror();
  EXPECT_EQ(in->spec().format, OIIO::TypeDesc::FLOAT);
  EXPECT_EQ(in->spec().nchannels, 3);
  EXPECT_EQ(in->spec().get_string_attribute("compression"), "zip");
  EXPECT_EQ(dir.Listing(), std::vector<std::string>{"round_trip.exr"});
}

TEST(ImageIO, ExrOverwriteReplacesTheFile) {
  ScratchDir dir;
  const std::string path = dir.File("out.exr");
  WriteEXR(path, Image(4, 4, RGB(1.f)));
  WriteEXR(path, Image(2, 3, RGB(0.25f, 0.5f, 0.75f)));
  const Image back = ReadImage(path);
  ASSERT_EQ(back.width, 2);
  ASSERT_EQ(back.height, 3);
  EXPECT_EQ(back.at(1, 2), RGB(0.25f, 0.5f, 0.75f));
  EXPECT_EQ(dir.Listing(), std::vector<std::string>{"out.exr"});
}

TEST(ImageIO, FailedWriteLeavesNoPartialOutput) {
  ScratchDir dir;
  const Image image(8, 8, RGB(0.5f));

  // Missing directory: the temporary file cannot even be created.
  const std::string missing = dir.File("no/such/dir/out.exr");
  EXPECT_THROW(WriteEXR(missing, image), std::runtime_error);
  EXPECT_FALSE(fs::exists(missing));

  // Target is a directory: the write succeeds, the final rename fails, and the temporary file
  // must be cleaned up, leaving the directory alone.
  fs::create_directory(dir.File("occupied.png"));
  try {
    WritePNG(dir.File("occupied.png"), image);
    ADD_FAILURE() << "writing over a directory should throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("occupied.png"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::is_directory(dir.File("occupied.png")));
  EXPECT_EQ(dir.Listing(), std::vector<std::string>{"occupied.png"});

  // An empty image is refused before anything is touched.
  EXPECT_THROW(WriteEXR(dir.File("empty.exr"), Image()), std::runtime_error);
  EXPECT_FALSE(fs::exists(dir.File("empty.exr")));
}

TEST(ImageIO, PngIsSrgbEncoded) {
  ScratchDir dir;
  Image image(6, 1);
  image.at(0, 0) = RGB(0.f, 0.5f, 1.f);
  image.at(1, 0) = RGB(2.f, -1.f, 0.001f);  // clamped high, clamped low, linear segment
  image.at(2, 0) = RGB(std::nanf(""), kInfinity, 0.05f);
  image.at(3, 0) = RGB(0.0031308f, 0.18f, 0.9f);
  const std::string path = dir.File("encoded.png");
  WritePNG(path, image);

  int w = 0, h = 0;
  const std::vector<uint8_t> bytes = ReadBytes(path, &w, &h);
  ASSERT_EQ(w, 6);
  ASSERT_EQ(h, 1);
  ASSERT_EQ(bytes.size(), 18u);
  EXPECT_EQ(bytes[0], 0);
  EXPECT_EQ(bytes[1], 188);  // 1.055 · 0.5^(1/2.4) − 0.055 = 0.7354 → 187.5 → 188
  EXPECT_EQ(bytes[2], 255);
  EXPECT_EQ(bytes[3], 255);
  EXPECT_EQ(bytes[4], 0);
  EXPECT_EQ(bytes[5], 3);    // 12.92 · 0.001 · 255 = 3.29
  EXPECT_EQ(bytes[6], 0);    // NaN
  EXPECT_EQ(bytes[7], 255);  // +Inf clamps to white
  EXPECT_EQ(bytes[8], 63);   // 1.055 · 0.05^(1/2.4) − 0.055 = 0.2478
  EXPECT_EQ(bytes[9], 10);   // end of the linear segment: 12.92 · 0.0031308 = 0.0405
  EXPECT_EQ(bytes[10], 118);
  EXPECT_EQ(bytes[11], 243);
  EXPECT_EQ(dir.Listing(), std::vector<std::string>{"encoded.png"});

  // Exposure scales before clamping: 0.25 · 2 = 0.5 → 188.
  WritePNG(path, Image(1, 1, RGB(0.25f)), 2.f);
  const std::vector<uint8_t> exposed = ReadBytes(path, &w, &h);
  EXPECT_EQ(exposed[0], 188);
  EXPECT_THROW(WritePNG(path, image, -1.f), std::runtime_error);
}

TEST(ImageIO, ReadsGreyAndExtraChannels) {
  ScratchDir dir;
  // One channel → grey.
  {
    const std::string path = dir.File("grey.exr");
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(3, 2, 1, OIIO::TypeDesc::FLOAT);
    ASSERT_TRUE(out->open(path, spec)) << out->geterror();
    const float data[6] = {0.f, 1.f, 2.f, 3.f, 4.f, 5.f};
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, data));
    out->close();
    const Image image = ReadImage(path);
    ASSERT_EQ(image.width, 3);
    ASSERT_EQ(image.height, 2);
    EXPECT_EQ(image.at(2, 1), RGB(5.f));  // row-major, y down
    EXPECT_EQ(image.at(1, 0), RGB(1.f));
  }
  // RGBA → the first three channels.
  {
    const std::string path = dir.File("rgba.exr");
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(2, 1, 4, OIIO::TypeDesc::FLOAT);
    ASSERT_TRUE(out->open(path, spec)) << out->geterror();
    const float data[8] = {1.f, 2.f, 3.f, 0.5f, 4.f, 5.f, 6.f, 1.f};
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, data));
    out->close();
    const Image image = ReadImage(path);
    ASSERT_EQ(image.width, 2);
    EXPECT_EQ(image.at(0, 0), RGB(1.f, 2.f, 3.f));
    EXPECT_EQ(image.at(1, 0), RGB(4.f, 5.f, 6.f));
  }
}

TEST(ImageIO, ReadErrorNamesTheFile) {
  ScratchDir dir;
  const std::string missing = dir.File("missing.exr");
  try {
    ReadImage(missing);
    FAIL() << "reading a missing file should throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
  const std::string garbage = dir.File("garbage.exr");
  std::ofstream(garbage) << "not an image";
  try {
    ReadImage(garbage);
    FAIL() << "reading a corrupt file should throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(garbage), std::string::npos) << e.what();
  }
}

// --- Resize ---------------------------------------------------------------------------------

TEST(Resize, DownsamplingIsTheAreaAverage) {
  // HDR content with fireflies, which a filter with negative lobes would ring around.
  Image image = RandomImage(1024, 1024, 7);
  Rng rng(8);
  for (int i = 0; i < 500; ++i) image.pixels[rng.UniformInt(1024 * 1024)] = RGB(1000.f);
  const Image small = ResizeImage(image, 128, 128);
  ASSERT_EQ(small.width, 128);
  ASSERT_EQ(small.height, 128);

  const double mean = MeanChannel(image);
  EXPECT_NEAR(MeanChannel(small), mean, 1e-3 * mean);

  // Each output pixel is the plain average of its 8×8 block, so nothing goes negative.
  for (int y = 0; y < 128; y += 9) {
    for (int x = 0; x < 128; x += 7) {
      double block = 0;
      for (int j = 0; j < 8; ++j)
        for (int i = 0; i < 8; ++i) block += double(image.at(8 * x + i, 8 * y + j).g);
      block /= 64;
      EXPECT_NEAR(small.at(x, y).g, block, 1e-5 * block + 1e-6) << x << "," << y;
    }
  }
  for (const RGB& p : small.pixels) ASSERT_GE(p.r, 0.f);
}

TEST(Resize, NonIntegerRatiosAndEnlarging) {
  const Image image = RandomImage(100, 60, 3);
  const double mean = MeanChannel(image);
  EXPECT_NEAR(MeanChannel(ResizeImage(image, 30, 20)), mean, 1e-2 * mean);
  EXPECT_NEAR(MeanChannel(ResizeImage(image, 200, 120)), mean, 1e-2 * mean);

  // Enlarging is bilinear interpolation: a ramp 0,1,2,3 doubled.
  Image ramp(4, 1);
  for (int x = 0; x < 4; ++x) ramp.at(x, 0) = RGB(float(x));
  const Image big = ResizeImage(ramp, 8, 1);
  const float expected[8] = {0.f, 0.25f, 0.75f, 1.25f, 1.75f, 2.25f, 2.75f, 3.f};
  for (int x = 0; x < 8; ++x) EXPECT_NEAR(big.at(x, 0).r, expected[x], 1e-5f) << x;

  EXPECT_THROW(ResizeImage(image, 0, 10), std::invalid_argument);
  // Same size is a copy.
  const Image same = ResizeImage(image, 100, 60);
  EXPECT_EQ(std::memcmp(same.pixels.data(), image.pixels.data(), image.PixelCount() * sizeof(RGB)),
            0);
}

// --- Metrics --------------------------------------------------------------------------------

TEST(Metrics, IdenticalImagesHaveZeroError) {
  const Image ref = RandomImage(16, 8, 11);
  const ErrorMetrics m = CompareImages(ref, ref);
  EXPECT_EQ(m.rel_l2, 0.0);
  EXPECT_EQ(m.rel_l1, 0.0);
  EXPECT_EQ(m.rmse, 0.0);
}

TEST(Metrics, ScaledImageHasTenPercentError) {
  const Image ref = RandomImage(16, 8, 12);
  Image img = ref;
  for (RGB& p : img.pixels)
    p = RGB(float(1.1 * double(p.r)), float(1.1 * double(p.g)), float(1.1 * double(p.b)));
  const ErrorMetrics m = CompareImages(ref, img);
  EXPECT_NEAR(m.rel_l2, 0.1, 1e-6);
  EXPECT_NEAR(m.rel_l1, 0.1, 1e-6);
  double sq = 0;
  for (const RGB& p : ref.pixels) {
    for (int c = 0; c < 3; ++c) sq += double(p[c]) * double(p[c]);
  }
  EXPECT_NEAR(m.rmse, 0.1 * std::sqrt(sq / (3.0 * 128)), 1e-6);
}

TEST(Metrics, HandComputedExample) {
  // ref = (1,2,2) and (0,0,0); img = (1,2,2) and (0,0,3): one channel differs by 3.
  Image ref(2, 1), img(2, 1);
  ref.at(0, 0) = img.at(0, 0) = RGB(1.f, 2.f, 2.f);
  img.at(1, 0) = RGB(0.f, 0.f, 3.f);
  const ErrorMetrics m = CompareImages(ref, img);
  EXPECT_DOUBLE_EQ(m.rel_l2, 1.0);  // 3 / sqrt(1 + 4 + 4)
  EXPECT_DOUBLE_EQ(m.rel_l1, 0.6);  // 3 / 5
  EXPECT_DOUBLE_EQ(m.rmse, std::sqrt(9.0 / 6.0));
}

// Specks: a black dot on a flat region and a bright one count; an edge the reference has does
// not (the image's pixel lies within its neighbourhood's range), nor does an unlit pixel.
TEST(Metrics, SpecksCountDotsTheReferenceLacksButNotItsEdges) {
  Image ref(8, 8), img(8, 8);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) ref.at(x, y) = RGB(x < 4 ? 1.f : 0.1f);  // an edge at x = 4
  ref.at(7, 7) = RGB(0.f);  // unlit
  img = ref;
  EXPECT_EQ(CompareImages(ref, img).speck_share, 0.0);
  img.at(4, 3) = RGB(1.f);  // the edge's dark side showing the bright side: within the 3×3 range
  img.at(7, 7) = RGB(5.f);  // unlit in the reference: not counted
  EXPECT_EQ(CompareImages(ref, img).speck_share, 0.0);
  img.at(1, 1) = RGB(0.f);   // black on the bright side
  img.at(6, 2) = RGB(0.4f);  // more than 3× the dark side's largest neighbour (0.1)
  const ErrorMetrics m = CompareImages(ref, img);
  EXPECT_EQ(m.dark_specks, 1u);
  EXPECT_EQ(m.bright_specks, 1u);
  EXPECT_DOUBLE_EQ(m.speck_share, 2.0 / 63.0);
}

TEST(Metrics, ExcludeAboveLeavesOutBrightReferencePixels) {
  // A bright reference pixel (an emitter's) that the image misses dominates the error; left out,
  // the rest is compared as if it were the whole image.
  Image ref(3, 1), img(3, 1);
  ref.at(0, 0) = img.at(0, 0) = RGB(1.f, 2.f, 2.f);
  ref.at(1, 0) = RGB(100.f, 0.f, 0.f);
  ref.at(2, 0) = RGB(0.f, 1.f, 0.f);
  img.at(2, 0) = RGB(0.f, 0.5f, 0.f);
  const ErrorMetrics all = CompareImages(ref, img);
  EXPECT_EQ(all.excluded_bright, 0u);
  EXPECT_GT(all.rel_l1, 0.9);
  const ErrorMetrics m = CompareImages(ref, img, 50.f);
  EXPECT_EQ(m.excluded_bright, 1u);
  EXPECT_DOUBLE_EQ(m.rel_l1, 0.5 / 6.0);
  EXPECT_DOUBLE_EQ(m.rmse, std::sqrt(0.25 / 6.0));
}

TEST(Metrics, RefusesWhatCannotBeCompared) {
  const Image a(4, 4, RGB(1.f)), b(4, 2, RGB(1.f));
  try {
    CompareImages(a, b);
    FAIL() << "different sizes should throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("4x4 vs 4x2"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ErrorHeatmap(a, b), std::runtime_error);
  try {
    CompareImages(Image(4, 4), a);
    FAIL() << "an all-zero reference should throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("all zero"), std::string::npos) << e.what();
  }
  Image nan = a;
  nan.at(1, 1).g = std::nanf("");
  EXPECT_THROW(CompareImages(a, nan), std::runtime_error);
  // A NaN in the reference (path tracers leave the odd one) is excluded and counted.
  Image scaled = a;
  scaled.at(2, 1).r *= 1.5f;
  Image ref_nan = a;
  ref_nan.at(2, 1).r = std::nanf("");
  const ErrorMetrics excl = CompareImages(ref_nan, scaled);
  EXPECT_EQ(excl.excluded_pixels, 1u);
  EXPECT_EQ(excl.rel_l2, 0.0);  // the only differing pixel is the excluded one
  EXPECT_EQ(CompareImages(a, scaled).excluded_pixels, 0u);
  EXPECT_GT(CompareImages(a, scaled).rel_l2, 0.0);
  EXPECT_THROW(CompareImages(Image(), Image()), std::runtime_error);
}

TEST(Metrics, HeatmapScale) {
  // Colour map: lightness (hence luminance) increases monotonically from near black.
  float previous = -1.f;
  for (int i = 0; i <= 100; ++i) {
    const float lum = HeatmapColor(i / 100.f).Luminance();
    EXPECT_GT(lum, previous) << i;
    previous = lum;
  }
  EXPECT_LT(HeatmapColor(0.f).Luminance(), 0.01f);
  EXPECT_GT(HeatmapColor(1.f).Luminance(), 0.8f);

  // Reference mean luminance is 1. Pixel 0 exact; pixel 1 off by max_error · mean (top);
  // pixel 2 is a dark pixel 100% off, which must stay near the bottom of the scale.
  Image ref(4, 1, RGB(1.f)), img(4, 1, RGB(1.f));
  ref.at(2, 0) = RGB(1e-3f);
  ref.at(3, 0) = RGB(2.f - 1e-3f);  // keeps the mean at 1 (up to float rounding)
  img.at(1, 0) = RGB(1.1f);
  img.at(2, 0) = RGB(2e-3f);
  img.at(3, 0) = ref.at(3, 0);
  const Image heat = ErrorHeatmap(ref, img, 0.1f);
  ASSERT_TRUE(heat.SameSize(ref));
  EXPECT_EQ(heat.at(0, 0), HeatmapColor(0.f));
  const RGB top = HeatmapColor(1.f);
  EXPECT_NEAR(heat.at(1, 0).r, top.r, 2e-2f);
  EXPECT_NEAR(heat.at(1, 0).g, top.g, 2e-2f);
  EXPECT_NEAR(heat.at(1, 0).b, top.b, 2e-2f);
  EXPECT_LT(heat.at(2, 0).Luminance(), HeatmapColor(0.02f).Luminance());
  EXPECT_THROW(ErrorHeatmap(ref, img, 0.f), std::runtime_error);
}

// --- Filters --------------------------------------------------------------------------------

struct FilterCase {
  FilterType type;
  Vec2 radius;  // (0, 0): default
};

std::unique_ptr<Filter> MakeFilter(const FilterCase& c) {
  return c.radius.x > 0 ? Filter::Create(c.type, c.radius) : Filter::Create(c.type);
}

std::string CaseName(const FilterCase& c) {
  return std::string(FilterTypeName(c.type)) + " radius " + std::to_string(c.radius.x) + "x" +
         std::to_string(c.radius.y);
}

const std::vector<FilterCase>& AllFilterCases() {
  static const std::vector<FilterCase> cases = {{FilterType::kBox, {}},
                                                {FilterType::kTriangle, {}},
                                                {FilterType::kGaussian, {}},
                                                {FilterType::kMitchell, {}},
                                                {FilterType::kLanczosSinc, {}},
                                                {FilterType::kBox, {1.f, 0.5f}},
                                                {FilterType::kGaussian, {2.f, 1.f}},
                                                {FilterType::kMitchell, {1.5f, 3.f}},
                                                {FilterType::kLanczosSinc, {2.f, 3.f}}};
  return cases;
}

// ∫ g over [-r, r]² by the midpoint rule on an n×n grid, in double.
template <typename F>
double Integrate(Vec2 r, int n, F g) {
  const double rx = r.x, ry = r.y;
  const double hx = 2.0 * rx / n, hy = 2.0 * ry / n;
  double sum = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      sum += double(g(Vec2(float(-rx + (i + 0.5) * hx), float(-ry + (j + 0.5) * hy))));
  return sum * hx * hy;
}

TEST(Filter, DefinitionsMatchPbrtV4) {
  EXPECT_EQ(Filter::Create(FilterType::kBox)->radius().x, 0.5f);
  EXPECT_EQ(Filter::Create(FilterType::kTriangle)->radius().x, 2.f);
  EXPECT_EQ(Filter::Create(FilterType::kGaussian)->radius().y, 1.5f);
  EXPECT_EQ(Filter::Create(FilterType::kMitchell)->radius().y, 2.f);
  EXPECT_EQ(Filter::Create(FilterType::kLanczosSinc)->radius().x, 4.f);

  EXPECT_FLOAT_EQ(Filter::Create(FilterType::kBox)->Evaluate({0.4f, -0.4f}), 1.f);
  EXPECT_FLOAT_EQ(Filter::Create(FilterType::kBox)->Evaluate({0.6f, 0.f}), 0.f);
  EXPECT_FLOAT_EQ(Filter::Create(FilterType::kTriangle)->Evaluate({0.f, 1.f}), 2.f);
  // Gaussian minus its value at the radius: 0 at the radius, (g(0) − g(1.5))² at the centre.
  const auto gaussian = Filter::Create(FilterType::kGaussian);
  EXPECT_FLOAT_EQ(gaussian->Evaluate({1.5f, 0.f}), 0.f);
  const double g0 = 1.0 / std::sqrt(2.0 * M_PI * 0.25);
  const double g15 = g0 * std::exp(-1.5 * 1.5 / 0.5);
  EXPECT_NEAR(gaussian->Evaluate({0.f, 0.f}), (g0 - g15) * (g0 - g15), 1e-5);
  // Mitchell B = C = 1/3 at the centre: ((6 − 2B) / 6)².
  EXPECT_NEAR(Filter::Create(FilterType::kMitchell)->Evaluate({0.f, 0.f}),
              std::pow((6.0 - 2.0 / 3.0) / 6.0, 2), 1e-6);
  EXPECT_NEAR(Filter::Create(FilterType::kMitchell)->Evaluate({2.f, 0.f}), 0.f, 1e-6);
  EXPECT_LT(Filter::Create(FilterType::kMitchell)->Evaluate({1.5f, 0.f}), 0.f);
  EXPECT_FLOAT_EQ(Filter::Create(FilterType::kLanczosSinc)->Evaluate({0.f, 0.f}), 1.f);
  EXPECT_NEAR(Filter::Create(FilterType::kLanczosSinc)->Evaluate({1.f, 0.f}), 0.f, 1e-6);
  EXPECT_LT(Filter::Create(FilterType::kLanczosSinc)->Evaluate({1.5f, 0.f}), 0.f);

  EXPECT_EQ(ParseFilterType("sinc"), FilterType::kLanczosSinc);
  EXPECT_EQ(ParseFilterType("gaussian"), FilterType::kGaussian);
  EXPECT_THROW(ParseFilterType("guassian"), OptionError);
  EXPECT_THROW(Filter::Create(FilterType::kBox, {0.f, 1.f}), OptionError);
  FilterShape bad;
  bad.sigma = -1.f;
  EXPECT_THROW(Filter::Create(FilterType::kGaussian, {1.f, 1.f}, bad), OptionError);
}

TEST(Filter, IntegralMatchesSamplerAverageWeight) {
  for (const FilterCase& c : AllFilterCases()) {
    SCOPED_TRACE(CaseName(c));
    const auto filter = MakeFilter(c);
    const double numeric =
        Integrate(filter->radius(), 2048, [&](Vec2 p) { return filter->Evaluate(p); });
    EXPECT_NEAR(filter->Integral(), numeric, 1e-3 * std::abs(numeric));

    // E[f/pdf] = ∫ f: average the weight over a 512² stratified grid of u.
    const FilterSampler sampler(*filter);
    constexpr int kN = 512;
    double sum = 0;
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i)
        sum += double(sampler.Sample({(i + 0.5f) / kN, (j + 0.5f) / kN}).weight);
    EXPECT_NEAR(sum / (kN * kN), numeric, 1e-2 * std::abs(numeric));
  }
}

TEST(Filter, SamplesStayInsideAndFollowAbsF) {
  for (const FilterCase& c : AllFilterCases()) {
    SCOPED_TRACE(CaseName(c));
    const auto filter = MakeFilter(c);
    const FilterSampler sampler(*filter);
    const Vec2 r = filter->radius();

    // The pdf is a density: it integrates to 1.
    EXPECT_NEAR(Integrate(r, 1024, [&](Vec2 p) { return sampler.Pdf(p); }), 1.0, 1e-3);

    // Histogram of samples on 8×8 bins against ∫_bin |f| / ∫ |f|.
    constexpr int kBins = 8;
    constexpr int kSamples = 400000;
    std::vector<double> expected(kBins * kBins, 0.0);
    constexpr int kSub = 64;  // quadrature points per bin and axis
    const double rx = r.x, ry = r.y;
    const double bw = 2.0 * rx / kBins, bh = 2.0 * ry / kBins;
    double total = 0;
    for (int by = 0; by < kBins; ++by)
      for (int bx = 0; bx < kBins; ++bx) {
        double s = 0;
        for (int j = 0; j < kSub; ++j)
          for (int i = 0; i < kSub; ++i)
            s +=
                std::abs(double(filter->Evaluate(Vec2(float(-rx + bw * (bx + (i + 0.5) / kSub)),
                                                      float(-ry + bh * (by + (j + 0.5) / kSub))))));
        expected[by * kBins + bx] = s;
        total += s;
      }
    std::vector<int> observed(kBins * kBins, 0);
    Rng rng(HashSeed({uint64_t(c.type), uint64_t(r.x * 16), uint64_t(r.y * 16)}));
    bool inside = true;
    for (int k = 0; k < kSamples; ++k) {
      const FilterSample s = sampler.Sample({rng.Uniform(), rng.Uniform()});
      inside &= std::abs(s.p.x) <= r.x && std::abs(s.p.y) <= r.y;
      const int bx = std::clamp(int((s.p.x + r.x) / (2.f * r.x) * kBins), 0, kBins - 1);
      const int by = std::clamp(int((s.p.y + r.y) / (2.f * r.y) * kBins), 0, kBins - 1);
      ++observed[by * kBins + bx];
    }
    EXPECT_TRUE(inside);
    double chi2 = 0;
    int dof = -1;
    for (int b = 0; b < kBins * kBins; ++b) {
      const double e = expected[b] / total * kSamples;
      if (e >= 20) {
        chi2 += (observed[b] - e) * (observed[b] - e) / e;
        ++dof;
      } else {
        EXPECT_LE(observed[b], 3 * e + 20) << "bin " << b;
      }
    }
    // Mean dof, standard deviation sqrt(2 dof): 6 sigma above the mean.
    EXPECT_LT(chi2, dof + 6 * std::sqrt(2.0 * dof)) << "dof " << dof;
  }
}

TEST(Filter, WeightSigns) {
  Rng rng(5);
  for (FilterType type : {FilterType::kBox, FilterType::kTriangle, FilterType::kGaussian}) {
    const FilterSampler sampler(*Filter::Create(type));
    const float first = sampler.Sample({0.5f, 0.5f}).weight;
    EXPECT_GT(first, 0.f) << FilterTypeName(type);
    for (int k = 0; k < 10000; ++k) {
      const float w = sampler.Sample({rng.Uniform(), rng.Uniform()}).weight;
      ASSERT_GT(w, 0.f) << FilterTypeName(type);
      ASSERT_NEAR(w, first, 1e-6f * first) << FilterTypeName(type);
    }
  }
  // Negative lobes give negative weights, with the same magnitude.
  for (FilterType type : {FilterType::kMitchell, FilterType::kLanczosSinc}) {
    const FilterSampler sampler(*Filter::Create(type));
    int negative = 0;
    for (int k = 0; k < 10000; ++k) {
      const FilterSample s = sampler.Sample({rng.Uniform(), rng.Uniform()});
      negative += s.weight < 0.f;
      ASSERT_NEAR(std::abs(s.weight), std::abs(sampler.Sample({0.5f, 0.5f}).weight), 1e-4f);
    }
    EXPECT_GT(negative, 50) << FilterTypeName(type);
    EXPECT_LT(negative, 5000) << FilterTypeName(type);
  }
}

// --- Film -----------------------------------------------------------------------------------

TEST(Film, ResolvesWeightedMeanAndSkipsNonFinite) {
  Film film(3, 2);
  const int p = film.PixelIndex(2, 1);
  film.AddSample(p, RGB(1.f, 2.f, 3.f), 1.f);
  film.AddSample(p, RGB(3.f, 0.f, 1.f), 3.f);
  film.AddSample(p, RGB(std::nanf(""), 0.f, 0.f), 1.f);
  film.AddSample(p, RGB(0.f, kInfinity, 0.f), 1.f);
  film.AddSample(p, RGB(1.f), std::nanf(""));
  film.AddSample(film.PixelIndex(0, 0), RGB(5.f), -0.5f);  // negative lobes are allowed
  EXPECT_EQ(film.nan_samples(), 3u);

  const Image image = film.Resolve();
  // (1·(1,2,3) + 3·(3,0,1)) / 4
  EXPECT_FLOAT_EQ(image.at(2, 1).r, 2.5f);
  EXPECT_FLOAT_EQ(image.at(2, 1).g, 0.5f);
  EXPECT_FLOAT_EQ(image.at(2, 1).b, 1.5f);
  EXPECT_FLOAT_EQ(image.at(0, 0).g, 5.f);
  EXPECT_EQ(image.at(1, 0), RGB(0.f));  // no samples
  EXPECT_EQ(image.CountNonFinite(), 0u);
  EXPECT_THROW(film.AddSample(6, RGB(1.f), 1.f), std::out_of_range);
  EXPECT_THROW(film.AddSample(-1, RGB(1.f), 1.f), std::out_of_range);
}

TEST(Film, MergeEqualsSingleFilmAndOrderDoesNotMatter) {
  Rng rng(99);
  struct S {
    int pixel;
    RGB L;
    float w;
  };
  std::vector<S> samples;
  for (int k = 0; k < 4000; ++k) {
    samples.push_back({int(rng.UniformInt(16)),
                       RGB(rng.Uniform(), rng.Uniform(), 100.f * rng.Uniform()),
                       rng.Uniform() - 0.2f});
  }
  Film all(4, 4), first(4, 4), second(4, 4), reversed(4, 4);
  for (size_t k = 0; k < samples.size(); ++k) {
    all.AddSample(samples[k].pixel, samples[k].L, samples[k].w);
    (k % 2 ? first : second).AddSample(samples[k].pixel, samples[k].L, samples[k].w);
  }
  for (size_t k = samples.size(); k-- > 0;) {
    reversed.AddSample(samples[k].pixel, samples[k].L, samples[k].w);
  }
  second.AddSample(0, RGB(kInfinity), 1.f);
  first.Merge(second);
  EXPECT_EQ(first.nan_samples(), 1u);
  const Image a = all.Resolve(), b = first.Resolve(), c = reversed.Resolve();
  for (size_t i = 0; i < a.PixelCount(); ++i) {
    EXPECT_EQ(a.pixels[i], b.pixels[i]) << i;
    EXPECT_EQ(a.pixels[i], c.pixels[i]) << i;
  }
  EXPECT_THROW(first.Merge(Film(2, 2)), std::invalid_argument);
}

TEST(Film, FilteredConstantRadianceIsExact) {
  // Whatever the weights (mitchell has negative ones), Σ w·L / Σ w of a constant is that constant.
  const FilterSampler sampler(*Filter::Create(FilterType::kMitchell));
  Film film(1, 1);
  Rng rng(3);
  for (int k = 0; k < 1000; ++k) {
    film.AddSample(0, RGB(0.7f, 0.2f, 0.1f), sampler.Sample({rng.Uniform(), rng.Uniform()}).weight);
  }
  const RGB v = film.Resolve().at(0, 0);
  EXPECT_NEAR(v.r, 0.7f, 1e-5f);
  EXPECT_NEAR(v.g, 0.2f, 1e-5f);
  EXPECT_NEAR(v.b, 0.1f, 1e-5f);
}

// --- Shared reference data ------------------------------------------------------------------

fs::path SharedDir() {
  if (const char* env = std::getenv("LIGHTFARM_SHARED"); env && *env) return env;
  return fs::path(LIGHTFARM_SOURCE_DIR) / ".." / "shared";
}

TEST(SharedReference, CornellBoxReferenceReads) {
  const fs::path shared = SharedDir();
  ASSERT_TRUE(fs::is_directory(shared))
      << "shared data directory " << shared
      << " not found: set LIGHTFARM_SHARED to the directory holding scenes/";
  const fs::path reference = shared / "scenes" / "cornell-box" / "reference.exr";
  ASSERT_TRUE(fs::exists(reference)) << reference << " is missing from the shared data";

  const Image image = ReadImage(reference.string());
  ASSERT_EQ(image.width, 1024);
  ASSERT_EQ(image.height, 1024);
  EXPECT_EQ(image.CountNonFinite(), 0u);
  const double mean = image.MeanLuminance();
  EXPECT_GT(mean, 0.0);

  // Downsampling to 128² keeps the mean within 0.1%.
  const Image small = ResizeImage(image, 128, 128);
  EXPECT_NEAR(small.MeanLuminance(), mean, 1e-3 * mean);
}

}  // namespace test_image
}  // namespace lightfarm
