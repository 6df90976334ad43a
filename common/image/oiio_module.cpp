// liblightfarm_imageio.so: image files through OpenImageIO, behind the ImageIoBackend table
// (image_io_backend.h says why it is a module). Links OpenImageIO and nothing of lightfarm.
#include <OpenImageIO/filter.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/image/image_io_backend.h"

namespace lightfarm {
namespace {

std::string SizeString(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

void ReadSize(const std::string& path, int* width, int* height) {
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path);
  if (!in) throw std::runtime_error("cannot read image \"" + path + "\": " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  *width = spec.full_width > 0 ? spec.full_width : spec.width;
  *height = spec.full_height > 0 ? spec.full_height : spec.height;
}

void Read(const std::string& path, int* width, int* height, std::vector<float>* rgb) {
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

  // Place it in the display window (they coincide for almost every file); grey from the first
  // channel when there are fewer than three.
  const int full_w = spec.full_width > 0 ? spec.full_width : spec.width;
  const int full_h = spec.full_height > 0 ? spec.full_height : spec.height;
  const int dx = spec.x - (spec.full_width > 0 ? spec.full_x : spec.x);
  const int dy = spec.y - (spec.full_height > 0 ? spec.full_y : spec.y);
  rgb->assign(static_cast<size_t>(full_w) * static_cast<size_t>(full_h) * 3, 0.f);
  for (int y = 0; y < spec.height; ++y) {
    const int iy = y + dy;
    if (iy < 0 || iy >= full_h) continue;
    for (int x = 0; x < spec.width; ++x) {
      const int ix = x + dx;
      if (ix < 0 || ix >= full_w) continue;
      const float* p = &data[(static_cast<size_t>(y) * static_cast<size_t>(spec.width) +
                              static_cast<size_t>(x)) *
                             static_cast<size_t>(nc)];
      float* q = &(*rgb)[(static_cast<size_t>(iy) * static_cast<size_t>(full_w) +
                          static_cast<size_t>(ix)) *
                         3];
      for (int c = 0; c < 3; ++c) q[c] = nc >= 3 ? p[c] : p[0];
    }
  }
  *width = full_w;
  *height = full_h;
}

void Write(const std::string& file, const char* format, int width, int height, bool float_pixels,
           const void* pixels) {
  OIIO::ImageSpec spec(width, height, 3, float_pixels ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8);
  if (std::string(format) == "openexr") {
    spec.attribute("compression", "zip");
    spec.attribute("oiio:ColorSpace", "Linear");
  } else {
    spec.attribute("oiio:ColorSpace", "sRGB");
  }
  // The writer is picked by format name: a temporary file's extension says nothing.
  std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(format);
  if (!out) {
    throw std::runtime_error(std::string("no OpenImageIO writer for ") + format + ": " +
                             OIIO::geterror());
  }
  if (!out->open(file, spec)) throw std::runtime_error(out->geterror());
  if (!out->write_image(spec.format, pixels)) {
    std::string why = out->geterror();
    out->close();
    throw std::runtime_error(why);
  }
  if (!out->close()) throw std::runtime_error(out->geterror());
}

void Resize(const float* rgb, int width, int height, float* out, int out_width, int out_height) {
  OIIO::ImageBuf src(OIIO::ImageSpec(width, height, 3, OIIO::TypeDesc::FLOAT));
  src.set_pixels(src.roi(), OIIO::TypeDesc::FLOAT, rgb);
  OIIO::ImageBuf dst(OIIO::ImageSpec(out_width, out_height, 3, OIIO::TypeDesc::FLOAT));

  // Choose the filter. OIIO expresses filter widths in destination pixels.
  // - Shrinking on both axes: a box one destination pixel wide, i.e. each output pixel is the
  //   plain average of the source pixels it covers. That is the area (integral) filter: it
  //   preserves the image mean exactly for integer ratios, and unlike OIIO's default lanczos3
  //   it has no negative lobes, so HDR fireflies cannot ring into negative or inflated
  //   neighbours — which would bias the error metrics computed against the result.
  // - Otherwise (enlarging on at least one axis): a tent two *source* pixels wide on enlarged
  //   axes (bilinear interpolation) and two destination pixels wide on shrunk ones. Still
  //   nonnegative, so no ringing; a box would leave gaps or blocks when enlarging.
  const float xratio = static_cast<float>(out_width) / static_cast<float>(width);
  const float yratio = static_cast<float>(out_height) / static_cast<float>(height);
  const bool shrinking = xratio <= 1.f && yratio <= 1.f;
  const char* name = shrinking ? "box" : "triangle";
  const float fw = shrinking ? 1.f : 2.f * std::max(1.f, xratio);
  const float fh = shrinking ? 1.f : 2.f * std::max(1.f, yratio);
  std::unique_ptr<OIIO::Filter2D, void (*)(OIIO::Filter2D*)> filter(
      OIIO::Filter2D::create(name, fw, fh), &OIIO::Filter2D::destroy);
  if (!filter) throw std::runtime_error(std::string("OpenImageIO has no filter ") + name);
  if (!OIIO::ImageBufAlgo::resize(dst, src, filter.get())) {
    throw std::runtime_error("resize to " + SizeString(out_width, out_height) +
                             " failed: " + dst.geterror());
  }
  if (!dst.get_pixels(dst.roi(), OIIO::TypeDesc::FLOAT, out)) {
    throw std::runtime_error("resize to " + SizeString(out_width, out_height) +
                             " failed: " + dst.geterror());
  }
}

void ContactSheet(const std::vector<std::pair<std::string, std::string>>& top,
                  const std::vector<std::string>& bottom, const std::string& path) {
  using namespace OIIO;
  if (top.empty()) return;
  ImageBuf first(top[0].second);
  if (!first.read(0, 0, true, TypeDesc::UINT8)) {
    throw std::runtime_error("cannot read image \"" + top[0].second + "\": " + first.geterror());
  }
  // Small renders are enlarged (nearest neighbour) so that pixels and labels stay readable.
  const int scale = std::max(1, (200 + first.spec().width - 1) / first.spec().width);
  const int w = first.spec().width * scale, h = first.spec().height * scale, label = 18;
  const int cols = int(top.size()), rows = bottom.empty() ? 1 : 2;
  ImageBuf sheet(ImageSpec(cols * w, rows * (h + label), 3, TypeDesc::UINT8));
  ImageBufAlgo::zero(sheet);
  auto paste = [&](const std::string& file, int col, int row) {
    ImageBuf src(file);
    if (!src.read(0, 0, true, TypeDesc::UINT8)) return;
    ImageBuf img = scale == 1 ? src : ImageBufAlgo::resample(src, false, ROI(0, w, 0, h, 0, 1, 0, 3));
    ImageBufAlgo::paste(sheet, col * w, row * (h + label) + label, 0, 0, img, ROI(0, w, 0, h, 0, 1, 0, 3));
  };
  for (int c = 0; c < cols; ++c) {
    paste(top[size_t(c)].second, c, 0);
    // Text needs a font; without one the sheet simply has no labels.
    ImageBufAlgo::render_text(sheet, c * w + 2, label - 4, top[size_t(c)].first, 13, "DejaVuSans",
                              {1.f, 1.f, 1.f});
  }
  for (size_t c = 0; c < bottom.size(); ++c)
    if (!bottom[c].empty()) paste(bottom[c], int(c), 1);
  if (!sheet.write(path)) {
    throw std::runtime_error("cannot write \"" + path + "\": " + sheet.geterror());
  }
}

const ImageIoBackend kBackend{&Read, &ReadSize, &Write, &Resize, &ContactSheet};

}  // namespace
}  // namespace lightfarm

extern "C" __attribute__((visibility("default"))) const lightfarm::ImageIoBackend*
lightfarm_image_io_backend() {
  return &lightfarm::kBackend;
}
