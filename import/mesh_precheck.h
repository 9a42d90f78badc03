#pragma once
// Checks of mesh files before assimp reads them. assimp 5.2 trusts what a
// file says of itself in places where a wrong word costs the whole process
// (an endless loop, a read past a buffer): the formats' own rules are
// checked here first, and a file that breaks them is refused with an
// InputError naming the file and the fault.
#include <string>

namespace triad {

// A PLY file: its header against the grammar ("ply", a format line, then
// comment, obj_info, element NAME COUNT, property TYPE NAME and property
// list TYPE TYPE NAME lines up to end_header, every element with a
// property, known types, and no control character but tabs), then its body
// against the header: every element's items present, and every list's
// count one that the rest of the file can hold.
void checkPly(const std::string& path);

// A glTF file (.gltf JSON, or binary glTF 2.0 under either extension): its
// JSON must parse, and every buffer, buffer view and accessor (sparse ones
// too) must lie inside the bytes its buffer really holds (a file beside it,
// a data URI, or the binary chunk), with valid component types and types.
void checkGltfLayout(const std::string& path);

// The indices of every primitive of a .gltf (buffers in files next to it)
// against its vertex count, so that an index out of range is named (assimp
// drops such a triangle, which then reads as a hole). What this check cannot
// read is left to assimp.
void checkGltfIndices(const std::string& path);

}  // namespace triad
