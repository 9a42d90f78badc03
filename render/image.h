#pragma once
// 8-bit RGB images in memory (rows top to bottom), and the CPU-side image
// operations of the preview renderer: box downsampling of a supersampled
// render, thumbnails and contact sheets, and the comparison metric of the
// golden-image tests.
#include <array>
#include <cstddef>
#include <string>
#include <cstdint>
#include <vector>

namespace triad::render {

struct Image {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> rgb;  // width * height * 3, row 0 at the top

  Image() = default;
  Image(int w, int h, uint8_t fill = 0) : width(w), height(h), rgb(size_t(w) * h * 3, fill) {}
  uint8_t* at(int x, int y) { return rgb.data() + (size_t(y) * width + x) * 3; }
  const uint8_t* at(int x, int y) const { return rgb.data() + (size_t(y) * width + x) * 3; }
  bool empty() const { return width <= 0 || height <= 0; }
};

// Averages factor x factor blocks of an RGBA8 buffer of (width*factor) x
// (height*factor) pixels whose rows run bottom-up (as glReadPixels returns
// them) into a top-down RGB image. Rounds to nearest: deterministic.
Image downsampleRgbaBottomUp(const uint8_t* rgba, int width, int height, int factor);

// Area-weighted resize to a smaller image (thumbnails); deterministic.
Image resizeDown(const Image& src, int width, int height);

// Draws `number` in a small 3x5 bitmap font, scaled by `scale`, with its top
// left corner at (x, y), clipped to the image.
void drawNumber(Image& img, int x, int y, int number, int scale, const uint8_t color[3]);
// The same for text: letters (drawn upper case), digits, space and - _ . ;
// other characters are drawn as '?'. Each character advances 4 * scale.
void drawText(Image& img, int x, int y, const std::string& text, int scale,
              const uint8_t color[3]);

// One line of a preview's legend: a colour swatch (linear 0..1, as the
// renderer's colours) and its label.
struct LegendEntry {
  std::string label;
  std::array<float, 3> color{0.7f, 0.7f, 0.7f};
};
// Draws the entries in the top left corner on a dark panel, one per line,
// scaled to the image's height (1 up to 400 pixels, 2 above).
void drawLegend(Image& img, const std::vector<LegendEntry>& entries);

// Thumbnails of `frames` laid out in a grid, left to right then top to bottom,
// each labelled with its number from `labels` (same length, or empty for none).
Image contactSheet(const std::vector<Image>& frames, const std::vector<int>& labels,
                   int thumb_width = 256, int max_columns = 8);
// The size contactSheet gives the thumbnails of frames of this size.
std::array<int, 2> thumbnailSize(int width, int height, int thumb_width = 256);
// contactSheet from thumbnails already made (resizeDown to thumbnailSize of
// the frames), all of one size.
Image contactSheetOfThumbnails(const std::vector<Image>& thumbs, const std::vector<int>& labels,
                               int max_columns = 8);

// The golden-image metric. Two images of the same size differ "visibly" at a
// pixel when the largest of the three channel differences exceeds
// `pixel_threshold` (0..255).
struct ImageDiff {
  bool same_size = false;
  double fraction_over = 1.0;  // share of pixels whose max channel difference > threshold
  double mean_abs = 255.0;     // mean |a - b| over every channel of every pixel, 0..255
  int max_abs = 255;           // largest channel difference
};
ImageDiff compareImages(const Image& a, const Image& b, int pixel_threshold = 24);

// A picture of the difference: the reference darkened to grey, with pixels
// over the threshold in red (brighter for larger differences).
Image diffImage(const Image& a, const Image& b, int pixel_threshold = 24);

}  // namespace triad::render
