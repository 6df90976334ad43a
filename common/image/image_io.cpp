#include "common/image/image_io.h"

#include <OpenImageIO/filter.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <system_error>
#include <vector>

namespace lightfarm {
namespace {

namespace fs = std::filesystem;

static_assert(sizeof(RGB) == 3 * sizeof(float), "Image pixels are passed to OIIO as float[3]");

std::string SizeString(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

void CheckWritable(const std::string& path, const Image& image) {
  if (image.Empty() || image.width <= 0 || image.height <= 0) {
    throw std::runtime_error("cannot write \"" + path + "\": the image is empty");
  }
  if (image.PixelCount() != static_cast<size_t>(image.width) * static_cast<size_t>(image.height)) {
    throw std::runtime_error("cannot write \"" + path + "\": image is " +
                             SizeString(image.width, image.height) + " but holds " +
                             std::to_string(image.PixelCount()) + " pixels");
  }
}

// A temporary name beside `path` (same directory, so rename() is atomic on POSIX), unique per
// process and call: ".NAME.tmp-PID-N".
fs::path TemporaryPathBeside(const fs::path& path) {
  static std::atomic<uint64_t> counter{0};
  fs::path name = "." + path.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                  std::to_string(counter.fetch_add(1));
  return path.parent_path() / name;
}

// Writes `pixels` (3 channels of `type`) with the OIIO plugin `format` to a temporary file and
// renames it over `path`; on any failure the temporary file is removed and `path` is untouched.
void WriteAtomically(const std::string& path, const char* format, OIIO::ImageSpec spec,
                     const void* pixels) {
  const fs::path target(path);
  const fs::path temporary = TemporaryPathBeside(target);
  auto fail = [&](const std::string& why) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw std::runtime_error("cannot write \"" + path + "\": " + why);
  };

  // Pick the plugin by format name: the temporary file's extension says nothing.
  std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(format);
  if (!out) fail(std::string("no OpenImageIO writer for ") + format + ": " + OIIO::geterror());
  if (!out->open(temporary.string(), spec)) fail(out->geterror());
  if (!out->write_image(spec.format, pixels)) {
    std::string why = out->geterror();
    out->close();
    fail(why);
  }
  if (!out->close()) fail(out->geterror());
  out.reset();

  std::error_code ec;
  fs::rename(temporary, target, ec);
  if (ec) fail("rename from temporary file failed: " + ec.message());
}

}  // namespace

float LinearToSRGB(float linear) {
  if (!(linear > 0.f)) return 0.f;  // also maps NaN to 0
  if (linear >= 1.f) return 1.f;
  if (linear <= 0.0031308f) return 12.92f * linear;
  return 1.055f * std::pow(linear, 1.f / 2.4f) - 0.055f;
}

uint8_t LinearToSRGB8(float linear) {
  return static_cast<uint8_t>(std::lround(LinearToSRGB(linear) * 255.f));
}

ImageSize ReadImageSize(const std::string& path) {
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path);
  if (!in) throw std::runtime_error("cannot read image \"" + path + "\": " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  return {spec.full_width > 0 ? spec.full_width : spec.width, spec.full_height > 0 ? spec.full_height : spec.height};
}

Image ReadImage(const std::string& path) {
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path);
  if (!in) {
    throw std::runtime_error("cannot read image \"" + path + "\": " + OIIO::geterror());
  }
  const OIIO::ImageSpec spec = in->spec();
  auto fail = [&](const std::string& why) -> void {
    throw std::runtime_error("cannot read image \"" + path + "\": " + why);
  };
  if (spec.deep) fail("deep images are not supported");
  if (spec.depth > 1) fail("volume images are not supported");
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0) fail("image is empty");

  // Read the data window, all channels, as float.
  const int nc = spec.nchannels;
  std::vector<float> data(static_cast<size_t>(spec.width) * static_cast<size_t>(spec.height) *
                          static_cast<size_t>(nc));
  if (!in->read_image(0, 0, 0, nc, OIIO::TypeDesc::FLOAT, data.data())) fail(in->geterror());
  in->close();

  // Place it in the display window (they coincide for almost every file).
  const int full_w = spec.full_width > 0 ? spec.full_width : spec.width;
  const int full_h = spec.full_height > 0 ? spec.full_height : spec.height;
  const int dx = spec.x - (spec.full_width > 0 ? spec.full_x : spec.x);
  const int dy = spec.y - (spec.full_height > 0 ? spec.full_y : spec.y);
  Image image(full_w, full_h);
  for (int y = 0; y < spec.height; ++y) {
    const int iy = y + dy;
    if (iy < 0 || iy >= full_h) continue;
    for (int x = 0; x < spec.width; ++x) {
      const int ix = x + dx;
      if (ix < 0 || ix >= full_w) continue;
      const float* p = &data[(static_cast<size_t>(y) * static_cast<size_t>(spec.width) +
                              static_cast<size_t>(x)) *
                             static_cast<size_t>(nc)];
      image.at(ix, iy) = nc >= 3 ? RGB(p[0], p[1], p[2]) : RGB(p[0]);
    }
  }
  return image;
}

void WriteEXR(const std::string& path, const Image& image) {
  CheckWritable(path, image);
  OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::FLOAT);
  spec.attribute("compression", "zip");
  spec.attribute("oiio:ColorSpace", "Linear");
  WriteAtomically(path, "openexr", spec, image.pixels.data());
}

void WritePNG(const std::string& path, const Image& image, float exposure) {
  CheckWritable(path, image);
  if (!(exposure >= 0.f) || !std::isfinite(exposure)) {
    throw std::runtime_error("cannot write \"" + path + "\": invalid exposure " +
                             std::to_string(exposure));
  }
  std::vector<uint8_t> encoded(image.PixelCount() * 3);
  for (size_t i = 0; i < image.PixelCount(); ++i) {
    for (int c = 0; c < 3; ++c) encoded[3 * i + c] = LinearToSRGB8(image.pixels[i][c] * exposure);
  }
  OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "sRGB");
  WriteAtomically(path, "png", spec, encoded.data());
}

Image ResizeImage(const Image& image, int width, int height) {
  if (width <= 0 || height <= 0) {
    throw std::invalid_argument("cannot resize to " + SizeString(width, height));
  }
  if (image.Empty()) throw std::invalid_argument("cannot resize an empty image");
  if (image.width == width && image.height == height) return image;

  OIIO::ImageBuf src(OIIO::ImageSpec(image.width, image.height, 3, OIIO::TypeDesc::FLOAT));
  src.set_pixels(src.roi(), OIIO::TypeDesc::FLOAT, image.pixels.data());
  OIIO::ImageBuf dst(OIIO::ImageSpec(width, height, 3, OIIO::TypeDesc::FLOAT));

  // Choose the filter. OIIO expresses filter widths in destination pixels.
  // - Shrinking on both axes: a box one destination pixel wide, i.e. each output pixel is the
  //   plain average of the source pixels it covers. That is the area (integral) filter: it
  //   preserves the image mean exactly for integer ratios, and unlike OIIO's default lanczos3
  //   it has no negative lobes, so HDR fireflies cannot ring into negative or inflated
  //   neighbours — which would bias the error metrics computed against the result.
  // - Otherwise (enlarging on at least one axis): a tent two *source* pixels wide on enlarged
  //   axes (bilinear interpolation) and two destination pixels wide on shrunk ones. Still
  //   nonnegative, so no ringing; a box would leave gaps or blocks when enlarging.
  const float xratio = static_cast<float>(width) / static_cast<float>(image.width);
  const float yratio = static_cast<float>(height) / static_cast<float>(image.height);
  const bool shrinking = xratio <= 1.f && yratio <= 1.f;
  const char* name = shrinking ? "box" : "triangle";
  const float fw = shrinking ? 1.f : 2.f * std::max(1.f, xratio);
  const float fh = shrinking ? 1.f : 2.f * std::max(1.f, yratio);
  std::unique_ptr<OIIO::Filter2D, void (*)(OIIO::Filter2D*)> filter(
      OIIO::Filter2D::create(name, fw, fh), &OIIO::Filter2D::destroy);
  if (!filter) throw std::runtime_error(std::string("OpenImageIO has no filter ") + name);
  if (!OIIO::ImageBufAlgo::resize(dst, src, filter.get())) {
    throw std::runtime_error("resize to " + SizeString(width, height) +
                             " failed: " + dst.geterror());
  }

  Image out(width, height);
  if (!dst.get_pixels(dst.roi(), OIIO::TypeDesc::FLOAT, out.pixels.data())) {
    throw std::runtime_error("resize to " + SizeString(width, height) +
                             " failed: " + dst.geterror());
  }
  return out;
}

}  // namespace lightfarm
