// The boundary between lightfarm and OpenImageIO. OpenImageIO pulls in ~300 shared libraries
// (OpenCV, ffmpeg, ...) whose loading and relocation cost every process about half a second at
// start, so it lives in a module, liblightfarm_imageio.so (oiio_module.cpp), that image_io.cpp
// loads on the first image read or written: commands and farm processes that touch no image
// never pay for it. The module is self-contained (it links no lightfarm code): pixels cross as
// interleaved RGB buffers. Both sides come from the same build and compiler, so standard C++
// types and exceptions cross too; every function throws std::runtime_error naming the file.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace lightfarm {

struct ImageIoBackend {
  // The first subimage as interleaved float RGB at display-window size (image_io.h, ReadImage).
  void (*read)(const std::string& path, int* width, int* height, std::vector<float>* rgb);
  // The display window's size, from the header alone.
  void (*read_size)(const std::string& path, int* width, int* height);
  // Writes interleaved RGB, 32-bit float (`float_pixels`) or 8-bit, with the writer named
  // `format` ("openexr": zip-compressed, linear; "png": sRGB) to `file`, whatever its extension.
  void (*write)(const std::string& file, const char* format, int width, int height,
                bool float_pixels, const void* pixels);
  // Resamples interleaved float RGB (image_io.h, ResizeImage, for the filters).
  void (*resize)(const float* rgb, int width, int height, float* out, int out_width,
                 int out_height);
  // image_io.h, WriteContactSheet.
  void (*contact_sheet)(const std::vector<std::pair<std::string, std::string>>& top,
                        const std::vector<std::string>& bottom, const std::string& path);
};

}  // namespace lightfarm

// The module's one exported symbol.
extern "C" const lightfarm::ImageIoBackend* lightfarm_image_io_backend();
