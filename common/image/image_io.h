// Reading and writing images through OpenImageIO, and resampling between resolutions.
// Every function throws std::runtime_error naming the file and OpenImageIO's reason on failure.
// OpenImageIO is loaded on the first call, from the liblightfarm_imageio.so module
// (image_io_backend.h): processes that touch no image never load it.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "common/image/image.h"

namespace lightfarm {

// Reads the first subimage of any format OpenImageIO understands (EXR, PNG, HDR, TIFF, ...)
// as linear float RGB. The first three channels are taken; an image with fewer than three
// channels is read as grey from its first channel. Integer formats are normalised to [0, 1]
// without colour decoding (an 8-bit PNG is returned as its encoded values / 255). An EXR whose
// data window is smaller than its display window is returned at display-window size, black
// outside the data window.
Image ReadImage(const std::string& path);

// Loads the image module now (every other function loads it on first use): a program that will
// write images calls it before hours of work, so a missing module fails at once, not at the end.
void RequireImageIo();

// The size ReadImage would return (the display window), from the file's header alone.
struct ImageSize {
  int width = 0, height = 0;
};
ImageSize ReadImageSize(const std::string& path);

// Writes linear float RGB OpenEXR (32-bit float channels R, G, B; zip compression).
// The file is written to a temporary file in the same directory and renamed over `path`, so a
// failed write never leaves a partial `path` behind (nor replaces an existing one).
void WriteEXR(const std::string& path, const Image& image);

// Writes an 8-bit sRGB PNG: each channel is clamp(x · exposure, 0, 1) (NaN → 0), encoded with
// the sRGB OETF and rounded to the nearest 8-bit value. Temporary file + rename as WriteEXR.
void WritePNG(const std::string& path, const Image& image, float exposure = 1.f);

// Resamples `image` to width × height with ImageBufAlgo::resize (see image_io.cpp for the
// filter choice). Downsampling preserves the image mean (exactly for integer ratios).
Image ResizeImage(const Image& image, int width, int height);

// Pastes PNGs into a grid: row 0 the `top` images (label, file), row 1 the `bottom` ones (an empty
// name leaves its cell black). Small images are enlarged (nearest neighbour) to about 200 pixels
// wide. Labels need a font; without one the sheet has none.
void WriteContactSheet(const std::vector<std::pair<std::string, std::string>>& top,
                       const std::vector<std::string>& bottom, const std::string& path);

// The sRGB OETF (IEC 61966-2-1) of a linear value in [0, 1], and its 8-bit quantisation as
// WritePNG applies it. Exposed for tests and for callers that encode colours themselves.
float LinearToSRGB(float linear);
uint8_t LinearToSRGB8(float linear);

}  // namespace lightfarm
