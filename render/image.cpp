#include "render/image.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>

namespace triad::render {

Image downsampleRgbaBottomUp(const uint8_t* rgba, int width, int height, int factor) {
  Image out(width, height);
  const int big_w = width * factor;
  const int n = factor * factor;
  for (int y = 0; y < height; ++y) {
    // Output row y (top-down) comes from buffer rows of the flipped block.
    const int row0 = (height - 1 - y) * factor;
    uint8_t* dst = out.at(0, y);
    for (int x = 0; x < width; ++x) {
      unsigned sum[3] = {0, 0, 0};
      for (int sy = 0; sy < factor; ++sy) {
        const uint8_t* src = rgba + (size_t(row0 + sy) * big_w + size_t(x) * factor) * 4;
        for (int sx = 0; sx < factor; ++sx, src += 4) {
          sum[0] += src[0];
          sum[1] += src[1];
          sum[2] += src[2];
        }
      }
      for (int c = 0; c < 3; ++c) dst[x * 3 + c] = uint8_t((sum[c] + unsigned(n / 2)) / unsigned(n));
    }
  }
  return out;
}

Image resizeDown(const Image& src, int width, int height) {
  Image out(width, height);
  if (src.empty() || width <= 0 || height <= 0) return out;
  // Exact area weights in integer-free double arithmetic; the order of
  // accumulation is fixed, so the result is deterministic.
  const double sx = double(src.width) / width, sy = double(src.height) / height;
  for (int y = 0; y < height; ++y) {
    const double y0 = y * sy, y1 = std::min(double(src.height), (y + 1) * sy);
    for (int x = 0; x < width; ++x) {
      const double x0 = x * sx, x1 = std::min(double(src.width), (x + 1) * sx);
      double acc[3] = {0, 0, 0}, wsum = 0;
      for (int iy = int(y0); iy < int(std::ceil(y1)) && iy < src.height; ++iy) {
        const double wy = std::min(y1, iy + 1.0) - std::max(y0, double(iy));
        if (wy <= 0) continue;
        for (int ix = int(x0); ix < int(std::ceil(x1)) && ix < src.width; ++ix) {
          const double wx = std::min(x1, ix + 1.0) - std::max(x0, double(ix));
          if (wx <= 0) continue;
          const uint8_t* p = src.at(ix, iy);
          const double w = wx * wy;
          for (int c = 0; c < 3; ++c) acc[c] += w * p[c];
          wsum += w;
        }
      }
      uint8_t* d = out.at(x, y);
      for (int c = 0; c < 3; ++c)
        d[c] = uint8_t(std::clamp(std::lround(acc[c] / std::max(wsum, 1e-12)), 0L, 255L));
    }
  }
  return out;
}

namespace {
// 3x5 glyphs, one row per 3 bits (MSB left), top row first.
constexpr uint8_t kDigits[10][5] = {
    {7, 5, 5, 5, 7}, {2, 6, 2, 2, 7}, {7, 1, 7, 4, 7}, {7, 1, 7, 1, 7}, {5, 5, 7, 1, 1},
    {7, 4, 7, 1, 7}, {7, 4, 7, 5, 7}, {7, 1, 1, 1, 1}, {7, 5, 7, 5, 7}, {7, 5, 7, 1, 7}};
constexpr uint8_t kLetters[26][5] = {
    {2, 5, 7, 5, 5}, {6, 5, 6, 5, 6}, {3, 4, 4, 4, 3}, {6, 5, 5, 5, 6}, {7, 4, 6, 4, 7},
    {7, 4, 6, 4, 4}, {3, 4, 5, 5, 3}, {5, 5, 7, 5, 5}, {7, 2, 2, 2, 7}, {1, 1, 1, 5, 2},
    {5, 5, 6, 5, 5}, {4, 4, 4, 4, 7}, {5, 7, 7, 5, 5}, {6, 5, 5, 5, 5}, {2, 5, 5, 5, 2},
    {6, 5, 6, 4, 4}, {2, 5, 5, 6, 3}, {6, 5, 6, 5, 5}, {3, 4, 2, 1, 6}, {7, 2, 2, 2, 2},
    {5, 5, 5, 5, 7}, {5, 5, 5, 5, 2}, {5, 5, 7, 7, 5}, {5, 5, 2, 5, 5}, {5, 5, 2, 2, 2},
    {7, 1, 2, 4, 7}};
constexpr uint8_t kSpace[5] = {0, 0, 0, 0, 0}, kDash[5] = {0, 0, 7, 0, 0},
                  kUnderscore[5] = {0, 0, 0, 0, 7}, kDot[5] = {0, 0, 0, 0, 2},
                  kUnknown[5] = {7, 1, 2, 0, 2};

const uint8_t* glyph(char c) {
  if (c >= '0' && c <= '9') return kDigits[c - '0'];
  if (c >= 'a' && c <= 'z') return kLetters[c - 'a'];
  if (c >= 'A' && c <= 'Z') return kLetters[c - 'A'];
  if (c == ' ') return kSpace;
  if (c == '-') return kDash;
  if (c == '_') return kUnderscore;
  if (c == '.') return kDot;
  return kUnknown;
}
}  // namespace

void drawNumber(Image& img, int x, int y, int number, int scale, const uint8_t color[3]) {
  drawText(img, x, y, std::to_string(number < 0 ? -number : number), scale, color);
}

void drawText(Image& img, int x, int y, const std::string& text, int scale,
              const uint8_t color[3]) {
  for (size_t k = 0; k < text.size(); ++k) {
    const uint8_t* g = glyph(text[k]);
    const int gx = x + int(k) * 4 * scale;
    for (int row = 0; row < 5; ++row)
      for (int col = 0; col < 3; ++col) {
        if (!((g[row] >> (2 - col)) & 1)) continue;
        for (int py = 0; py < scale; ++py)
          for (int px = 0; px < scale; ++px) {
            const int ix = gx + col * scale + px, iy = y + row * scale + py;
            if (ix < 0 || iy < 0 || ix >= img.width || iy >= img.height) continue;
            std::copy(color, color + 3, img.at(ix, iy));
          }
      }
  }
}

void drawLegend(Image& img, const std::vector<LegendEntry>& entries) {
  if (entries.empty() || img.empty()) return;
  const int scale = img.height > 400 ? 2 : 1;
  const int line = 7 * scale, pad = 2 * scale, swatch = 5 * scale;
  size_t longest = 0;
  for (const LegendEntry& e : entries) longest = std::max(longest, e.label.size());
  const int w = std::min(img.width, pad * 3 + swatch + int(longest) * 4 * scale);
  const int h = std::min(img.height, pad * 2 + int(entries.size()) * line);
  // A dark panel, half blended over the picture.
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      uint8_t* p = img.at(x, y);
      for (int c = 0; c < 3; ++c) p[c] = uint8_t(p[c] / 4 + 16);
    }
  const uint8_t text[3] = {235, 235, 235};
  for (size_t i = 0; i < entries.size(); ++i) {
    const int y0 = pad + int(i) * line;
    if (y0 + swatch > img.height) break;
    uint8_t rgb[3];
    for (int c = 0; c < 3; ++c)
      rgb[c] = uint8_t(std::clamp(std::lround(entries[i].color[size_t(c)] * 255.0f), 0L, 255L));
    for (int y = 0; y < swatch; ++y)
      for (int x = 0; x < swatch && pad + x < img.width; ++x) std::copy(rgb, rgb + 3, img.at(pad + x, y0 + y));
    drawText(img, pad * 2 + swatch, y0, entries[i].label, scale, text);
  }
}

std::array<int, 2> thumbnailSize(int width, int height, int thumb_width) {
  const int tw = std::max(8, std::min(thumb_width, width));
  return {tw, std::max(1, int(std::lround(double(tw) * height / std::max(1, width))))};
}

Image contactSheet(const std::vector<Image>& frames, const std::vector<int>& labels,
                   int thumb_width, int max_columns) {
  if (frames.empty()) return Image();
  const auto [tw, th] = thumbnailSize(frames.front().width, frames.front().height, thumb_width);
  std::vector<Image> thumbs;
  for (const Image& f : frames) thumbs.push_back(resizeDown(f, tw, th));
  return contactSheetOfThumbnails(thumbs, labels, max_columns);
}

Image contactSheetOfThumbnails(const std::vector<Image>& thumbs, const std::vector<int>& labels,
                               int max_columns) {
  if (thumbs.empty()) return Image();
  const int tw = thumbs.front().width, th = thumbs.front().height;
  const int n = int(thumbs.size());
  const int cols = std::max(1, std::min(n, max_columns));
  const int rows = (n + cols - 1) / cols;
  const int gap = 4;
  Image sheet(cols * tw + (cols + 1) * gap, rows * th + (rows + 1) * gap, 40);
  const uint8_t text_bg[3] = {0, 0, 0}, text_fg[3] = {255, 255, 255};
  for (int i = 0; i < n; ++i) {
    const Image& thumb = thumbs[size_t(i)];
    const int ox = gap + (i % cols) * (tw + gap), oy = gap + (i / cols) * (th + gap);
    for (int y = 0; y < th; ++y)
      std::copy(thumb.at(0, y), thumb.at(0, y) + size_t(tw) * 3, sheet.at(ox, oy + y));
    if (labels.size() == thumbs.size()) {
      const int scale = tw >= 192 ? 2 : 1;
      const int digits = int(std::to_string(labels[size_t(i)]).size());
      const int bw = digits * 4 * scale + scale, bh = 7 * scale;
      for (int y = 0; y < bh && y < th; ++y)
        for (int x = 0; x < bw && x < tw; ++x) std::copy(text_bg, text_bg + 3, sheet.at(ox + x, oy + y));
      drawNumber(sheet, ox + scale, oy + scale, labels[size_t(i)], scale, text_fg);
    }
  }
  return sheet;
}

ImageDiff compareImages(const Image& a, const Image& b, int pixel_threshold) {
  ImageDiff d;
  if (a.width != b.width || a.height != b.height || a.empty()) return d;
  d.same_size = true;
  size_t over = 0;
  uint64_t sum = 0;
  int max_abs = 0;
  const size_t pixels = size_t(a.width) * a.height;
  for (size_t i = 0; i < pixels; ++i) {
    int m = 0;
    for (int c = 0; c < 3; ++c) {
      const int diff = std::abs(int(a.rgb[i * 3 + c]) - int(b.rgb[i * 3 + c]));
      sum += unsigned(diff);
      m = std::max(m, diff);
    }
    if (m > pixel_threshold) ++over;
    max_abs = std::max(max_abs, m);
  }
  d.fraction_over = double(over) / double(pixels);
  d.mean_abs = double(sum) / double(pixels * 3);
  d.max_abs = max_abs;
  return d;
}

Image diffImage(const Image& a, const Image& b, int pixel_threshold) {
  const int w = std::min(a.width, b.width), h = std::min(a.height, b.height);
  Image out(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const uint8_t* pa = a.at(x, y);
      const uint8_t* pb = b.at(x, y);
      int m = 0;
      for (int c = 0; c < 3; ++c) m = std::max(m, std::abs(int(pa[c]) - int(pb[c])));
      uint8_t* o = out.at(x, y);
      if (m > pixel_threshold) {
        o[0] = uint8_t(std::min(255, 128 + m));
        o[1] = o[2] = 0;
      } else {
        const uint8_t grey = uint8_t((int(pb[0]) + pb[1] + pb[2]) / 9);
        o[0] = uint8_t(std::min(255, grey + m * 4));
        o[1] = o[2] = grey;
      }
    }
  return out;
}

}  // namespace triad::render
