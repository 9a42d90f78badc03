#pragma once
// Reads particle positions and object indices back from a cache's
// `particles/particles.FFFF.ply` (binary little-endian PLY with float x y z
// and an integer `object` property, as export/ply_writer.cpp writes it; any
// other properties are skipped).
#include <cstdint>
#include <string>
#include <vector>

#include "render/preview_renderer.h"

namespace triad::render {

// Fills frame.xyz and frame.object, and `ids` (when given) from the integer
// property `id`. Throws triad::InputError naming the file for anything that
// is not such a PLY (bad header, missing properties, truncated data, object
// index out of range 0..65535).
void readParticlesPly(const std::string& path, PreviewFrame& frame,
                      std::vector<uint32_t>* ids = nullptr);

}  // namespace triad::render
