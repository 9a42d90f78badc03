#pragma once
// PNG files through libpng: 8-bit RGB, no timestamp and no text chunks, so the
// same pixels always give the same bytes. Files are written atomically: to a
// temporary name in the same directory, then renamed over the target.
#include <string>

#include "render/image.h"

namespace triad::render {

// Throws std::runtime_error naming the file on any failure; the target is
// then left as it was and no temporary remains.
void writePng(const std::string& path, const Image& image);

// Reads an 8-bit or 16-bit PNG of any colour type into RGB (alpha dropped,
// grey expanded). Throws std::runtime_error naming the file.
Image readPng(const std::string& path);

}  // namespace triad::render
