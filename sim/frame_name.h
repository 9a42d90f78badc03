// Names of a cache's per-frame files, STEM.FRAME.EXT with FRAME in decimal
// digits, read back when a cache is listed, resumed or tidied (export,
// render and the command line all read them).
#pragma once

#include <string>

namespace triad {

struct FrameName {
  std::string stem;  // everything before the frame's dot (never empty)
  int frame = -1;
  std::string ext;  // after the last dot
};

// Splits `name`: the extension after its last dot, the frame the digits
// between that and the dot before (min_digits to max_digits of them, at
// most 9 so that any frame fits an int), the stem all before. False when
// the name has no such parts.
inline bool parseFrameName(const std::string& name, FrameName& out, int min_digits = 4,
                           int max_digits = 9) {
  const size_t e = name.rfind('.');
  if (e == std::string::npos || e < 2) return false;
  const size_t d = name.rfind('.', e - 1);
  if (d == std::string::npos || d == 0) return false;
  const size_t digits = e - d - 1;
  if (digits < size_t(min_digits) || digits > size_t(max_digits) || digits > 9) return false;
  int frame = 0;
  for (size_t k = d + 1; k < e; ++k) {
    if (name[k] < '0' || name[k] > '9') return false;
    frame = frame * 10 + (name[k] - '0');
  }
  out.stem = name.substr(0, d);
  out.frame = frame;
  out.ext = name.substr(e + 1);
  return true;
}

// Whether `name` is one of the temporaries an atomic write leaves behind if
// it is killed: NAME.tmpDIGITS.
inline bool isTemporaryName(const std::string& name) {
  const size_t k = name.rfind(".tmp");
  if (k == std::string::npos || k == 0 || k + 4 >= name.size()) return false;
  for (size_t i = k + 4; i < name.size(); ++i)
    if (name[i] < '0' || name[i] > '9') return false;
  return true;
}

}  // namespace triad
