// libFuzzer target: any bytes as a scene file. The loader must answer with
// a scene or an InputError (exit 2 in the program), never crash, hang or
// throw anything else. Built and run by scripts/fuzz.sh.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "import/scene_loader.h"
#include "sim/errors.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // The loader reads files (it checks duplicate keys in the text itself).
  static const std::string path = [] {
    char tmpl[] = "/tmp/triad_fuzz_scene_XXXXXX";
    const int fd = mkstemp(tmpl);
    if (fd >= 0) close(fd);
    return std::string(tmpl);
  }();
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) std::abort();
  std::fwrite(data, 1, size, f);
  std::fclose(f);
  try {
    triad::loadScene(path);
  } catch (const triad::InputError&) {
  }
  return 0;
}
