// libFuzzer target: any bytes as a mesh file of the formats the importer
// reads (the first byte picks OBJ, STL, PLY or glTF). Loading and repair
// must answer with a mesh or an InputError naming the file, never crash or
// throw anything else. Built and run by scripts/fuzz.sh.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "import/mesh_loader.h"
#include "sim/errors.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* kExt[] = {".obj", ".stl", ".ply", ".gltf"};
  // One directory per process, its name always as long (mkdtemp): a path
  // whose length varied with the process id varied the loops over it, so
  // the coverage, so the inputs a fixed seed explores.
  static const std::string dir = [] {
    char tmpl[] = "/tmp/triad_fuzz_mesh_XXXXXX";
    if (!mkdtemp(tmpl)) std::abort();
    return std::string(tmpl);
  }();
  const std::string path = dir + "/mesh" + kExt[data[0] % 4];
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) std::abort();
  std::fwrite(data + 1, 1, size - 1, f);
  std::fclose(f);
  try {
    triad::loadMeshFile(path);
  } catch (const triad::InputError&) {
  }
  return 0;
}
