// Whole files as bytes: scene files to upload, token files, images the coordinator streams.
#pragma once

#include <string>

namespace lightfarm {

// The file's contents; throws std::runtime_error("cannot read PATH") when it cannot be opened.
std::string ReadFile(const std::string& path);

}  // namespace lightfarm
