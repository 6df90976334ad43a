#include "common/image/image_io.h"

#include <dlfcn.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <system_error>
#include <vector>

#include "common/image/image_io_backend.h"
#include "common/util/file.h"

namespace lightfarm {
namespace {

namespace fs = std::filesystem;

constexpr const char* kModuleName = "liblightfarm_imageio.so";

static_assert(sizeof(RGB) == 3 * sizeof(float), "Image pixels cross to the module as float[3]");

// Where the module may be: $LIGHTFARM_IMAGEIO_MODULE alone when it is set; else, in order,
// beside the running program (the build tree), ../lib/lightfarm from it (an installed tree,
// CMakeLists.txt's install rules), the path it was built at (programs in subfolders of the build
// tree, such as the fuzz targets).
std::vector<fs::path> ModuleCandidates() {
  std::vector<fs::path> out;
  if (const char* env = std::getenv("LIGHTFARM_IMAGEIO_MODULE"); env && *env) return {fs::path(env)};
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    out.push_back(exe.parent_path() / kModuleName);
    out.push_back(exe.parent_path().parent_path() / "lib" / "lightfarm" / kModuleName);
  }
#ifdef LIGHTFARM_IMAGEIO_MODULE_PATH
  out.emplace_back(LIGHTFARM_IMAGEIO_MODULE_PATH);
#endif
  return out;
}

const ImageIoBackend* LoadBackend() {
  std::string tried;
  for (const fs::path& candidate : ModuleCandidates()) {
    std::error_code ec;
    if (!fs::exists(candidate, ec)) {
      tried += "; " + candidate.string() + ": no such file";
      continue;
    }
    // Kept for the life of the process (never dlclose'd: its objects may be referenced until exit).
    void* handle = ::dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      tried += "; " + candidate.string() + ": " + ::dlerror();
      continue;
    }
    using Entry = const ImageIoBackend* (*)();
    auto entry = reinterpret_cast<Entry>(::dlsym(handle, "lightfarm_image_io_backend"));
    if (!entry) {
      tried += "; " + candidate.string() + ": not lightfarm's image module";
      continue;
    }
    return entry();
  }
  // One line, as every error a user sees.
  throw std::runtime_error(std::string("image I/O needs ") + kModuleName +
                           " (lightfarm's OpenImageIO module), which could not be loaded" + tried);
}

// Loaded on first use; a failed load throws and is retried by the next call.
const ImageIoBackend& Backend() {
  static const ImageIoBackend* backend = LoadBackend();
  return *backend;
}

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

// Writes the pixels to a temporary file and renames it over `path` (ReplaceFileAtomically).
void WriteAtomically(const std::string& path, const char* format, const Image& image,
                     bool float_pixels, const void* pixels) {
  const ImageIoBackend& backend = Backend();
  ReplaceFileAtomically(path, [&](const fs::path& temporary) {
    backend.write(temporary.string(), format, image.width, image.height, float_pixels, pixels);
  });
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

void RequireImageIo() { Backend(); }

ImageSize ReadImageSize(const std::string& path) {
  ImageSize size;
  Backend().read_size(path, &size.width, &size.height);
  return size;
}

Image ReadImage(const std::string& path) {
  int width = 0, height = 0;
  std::vector<float> rgb;
  Backend().read(path, &width, &height, &rgb);
  Image image(width, height);
  for (size_t i = 0; i < image.PixelCount(); ++i) {
    image.pixels[i] = RGB(rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]);
  }
  return image;
}

void WriteEXR(const std::string& path, const Image& image) {
  CheckWritable(path, image);
  WriteAtomically(path, "openexr", image, true, image.pixels.data());
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
  WriteAtomically(path, "png", image, false, encoded.data());
}

Image ResizeImage(const Image& image, int width, int height) {
  if (width <= 0 || height <= 0) {
    throw std::invalid_argument("cannot resize to " + SizeString(width, height));
  }
  if (image.Empty()) throw std::invalid_argument("cannot resize an empty image");
  if (image.width == width && image.height == height) return image;
  Image out(width, height);
  Backend().resize(reinterpret_cast<const float*>(image.pixels.data()), image.width, image.height,
                   reinterpret_cast<float*>(out.pixels.data()), width, height);
  return out;
}

void WriteContactSheet(const std::vector<std::pair<std::string, std::string>>& top,
                       const std::vector<std::string>& bottom, const std::string& path) {
  Backend().contact_sheet(top, bottom, path);
}

}  // namespace lightfarm
