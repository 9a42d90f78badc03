#pragma once
// `triad compare CACHE_A CACHE_B`: golden-image regression checks for users.
// Compares the previews frame by frame with the golden tests' metric
// (render::compareImages: a pixel differs when a channel differs by more
// than the threshold; a frame passes when few pixels differ and the mean
// difference is small) and, where both hold particles, the particles by id
// (RMS and largest position difference, ids present in one only). Writes a
// diff image per frame and a contact sheet of them, prints one line per
// frame, and returns 0 when every frame is within tolerance, 1 when one is
// not, 2 for bad input (no such cache, unreadable files). B may be a
// golden folder holding only preview/ (and optionally particles/).
#include <string>

namespace triad {

struct CompareOptions {
  std::string a, b;
  std::string out;              // diff images; default A/compare
  int pixel_threshold = 24;     // 0..255, per channel
  double max_fraction = 0.002;  // of pixels over the threshold
  double max_mean = 1.0;        // mean |difference| over channels, 0..255
  double max_rms = -1.0;        // m; < 0: the domain's size times 1e-4 (run.json), else 1e-4 m
  double max_position = -1.0;   // m; < 0: 10 times max_rms
};

int compareCaches(const CompareOptions& options);

}  // namespace triad
