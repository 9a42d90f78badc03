#pragma once
// The scalar types of the PLY format, shared by everything that reads PLY
// files (the mesh check before assimp, the preview's cache readers). Here
// because every library of the project depends on sim/.
#include <string>

namespace triad {

// Bytes of a PLY scalar type by any of its names; 0 for a name PLY does not have.
inline int plyTypeBytes(const std::string& t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" || t == "float32")
    return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

}  // namespace triad
