// GIF89a writer (see gif_writer.h).
#include "uplvsm/io/gif_writer.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/video_frames.h"

namespace uplvsm::io {
namespace {

using Colour = std::array<uint8_t, 3>;

// ---------------------------------------------------------------------------------------------------------------
// Palette: exact when <= 256 colours, else median cut over a 15-bit histogram (true colour sums per bin)
// ---------------------------------------------------------------------------------------------------------------

uint32_t key24(const uint8_t* p) { return (uint32_t(p[0]) << 16) | (uint32_t(p[1]) << 8) | p[2]; }

// The distinct colours when there are at most 256 of them, else empty.
std::vector<Colour> exact_colours(const std::vector<torch::Tensor>& frames) {
  std::unordered_set<uint32_t> seen;
  uint32_t last = 0xFFFFFFFF;
  for (const auto& f : frames) {
    const uint8_t* p = f.data_ptr<uint8_t>();
    for (int64_t i = 0, n = f.numel() / 3; i < n; ++i, p += 3) {
      uint32_t k = key24(p);
      if (k == last) continue;
      last = k;
      if (seen.insert(k).second && seen.size() > 256) return {};
    }
  }
  std::vector<uint32_t> keys(seen.begin(), seen.end());
  std::sort(keys.begin(), keys.end());
  std::vector<Colour> out;
  for (uint32_t k : keys) out.push_back({uint8_t(k >> 16), uint8_t(k >> 8), uint8_t(k)});
  return out;
}

struct HistBin {
  uint64_t count = 0;
  uint64_t sum[3] = {0, 0, 0};
};

int bin_coord(int bin, int axis) { return (bin >> (10 - 5 * axis)) & 31; }

struct Box {
  std::vector<int> bins;
  uint64_t count = 0;
  int longest_axis = 0, extent = 0;
};

Box make_box(std::vector<int> bins, const std::vector<HistBin>& hist) {
  Box b;
  b.bins = std::move(bins);
  int lo[3] = {31, 31, 31}, hi[3] = {0, 0, 0};
  for (int bin : b.bins) {
    b.count += hist[bin].count;
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], bin_coord(bin, a));
      hi[a] = std::max(hi[a], bin_coord(bin, a));
    }
  }
  for (int a = 0; a < 3; ++a)
    if (hi[a] - lo[a] > b.extent) b.extent = hi[a] - lo[a], b.longest_axis = a;
  return b;
}

// Splits a box at the pixel-weighted median of its longest axis; both halves are non-empty.
std::pair<Box, Box> split_box(Box box, const std::vector<HistBin>& hist) {
  int axis = box.longest_axis;
  std::sort(box.bins.begin(), box.bins.end(), [axis](int a, int b) { return bin_coord(a, axis) < bin_coord(b, axis); });
  uint64_t half = box.count / 2, acc = 0;
  size_t cut = 1;
  for (; cut < box.bins.size(); ++cut) {
    acc += hist[box.bins[cut - 1]].count;
    if (acc >= half) break;
  }
  cut = std::clamp<size_t>(cut, 1, box.bins.size() - 1);
  std::vector<int> left(box.bins.begin(), box.bins.begin() + cut), right(box.bins.begin() + cut, box.bins.end());
  return {make_box(std::move(left), hist), make_box(std::move(right), hist)};
}

std::vector<Colour> median_cut(const std::vector<torch::Tensor>& frames, size_t max_colours) {
  std::vector<HistBin> hist(32768);
  for (const auto& f : frames) {
    const uint8_t* p = f.data_ptr<uint8_t>();
    for (int64_t i = 0, n = f.numel() / 3; i < n; ++i, p += 3) {
      HistBin& h = hist[((p[0] >> 3) << 10) | ((p[1] >> 3) << 5) | (p[2] >> 3)];
      ++h.count;
      for (int c = 0; c < 3; ++c) h.sum[c] += p[c];
    }
  }
  std::vector<int> used;
  for (int i = 0; i < 32768; ++i)
    if (hist[i].count) used.push_back(i);
  std::vector<Box> boxes{make_box(std::move(used), hist)};
  while (boxes.size() < max_colours) {
    // Split the box with the most pixels times colour extent: big, spread-out boxes cost the most error.
    size_t best = boxes.size();
    double best_score = 0;
    for (size_t i = 0; i < boxes.size(); ++i) {
      double score = double(boxes[i].count) * boxes[i].extent;
      if (boxes[i].bins.size() > 1 && score > best_score) best = i, best_score = score;
    }
    if (best == boxes.size()) break;
    auto [a, b] = split_box(std::move(boxes[best]), hist);
    boxes[best] = std::move(a);
    boxes.push_back(std::move(b));
  }
  std::vector<Colour> palette;
  for (const Box& b : boxes) {
    uint64_t sum[3] = {0, 0, 0};
    for (int bin : b.bins)
      for (int c = 0; c < 3; ++c) sum[c] += hist[bin].sum[c];
    Colour col;
    for (int c = 0; c < 3; ++c) col[c] = uint8_t((sum[c] + b.count / 2) / b.count);
    palette.push_back(col);
  }
  return palette;
}

// ---------------------------------------------------------------------------------------------------------------
// Pixel -> palette index
// ---------------------------------------------------------------------------------------------------------------

// Nearest palette entries cached on a 6-bit-per-channel grid (filled lazily), or an exact map for exact palettes.
struct ColourMapper {
  const std::vector<Colour>& palette;
  bool exact;
  std::unordered_map<uint32_t, uint8_t> exact_index;
  std::vector<int16_t> lut;

  ColourMapper(const std::vector<Colour>& pal, bool is_exact) : palette(pal), exact(is_exact) {
    if (exact)
      for (size_t i = 0; i < pal.size(); ++i) exact_index[key24(pal[i].data())] = uint8_t(i);
    else
      lut.assign(1 << 18, -1);
  }

  uint8_t nearest(int r, int g, int b) {
    int key = ((r >> 2) << 12) | ((g >> 2) << 6) | (b >> 2);
    if (lut[key] >= 0) return uint8_t(lut[key]);
    int cr = (r & ~3) + 2, cg = (g & ~3) + 2, cb = (b & ~3) + 2;
    int best = 0, best_d = INT32_MAX;
    for (size_t i = 0; i < palette.size(); ++i) {
      int dr = cr - palette[i][0], dg = cg - palette[i][1], db = cb - palette[i][2];
      int d = 2 * dr * dr + 4 * dg * dg + db * db;  // rough perceptual weights
      if (d < best_d) best_d = d, best = int(i);
    }
    lut[key] = int16_t(best);
    return uint8_t(best);
  }
};

const int kBayer4[4][4] = {{0, 8, 2, 10}, {12, 4, 14, 6}, {3, 11, 1, 9}, {15, 7, 13, 5}};

std::vector<uint8_t> index_frame(const torch::Tensor& frame, ColourMapper& mapper, bool dither) {
  int64_t h = frame.size(0), w = frame.size(1);
  std::vector<uint8_t> out(size_t(h * w));
  const uint8_t* p = frame.data_ptr<uint8_t>();
  for (int64_t y = 0; y < h; ++y) {
    for (int64_t x = 0; x < w; ++x, p += 3) {
      size_t i = size_t(y * w + x);
      if (mapper.exact) {
        out[i] = mapper.exact_index.at(key24(p));
        continue;
      }
      int offset = dither ? (kBayer4[y & 3][x & 3] * 2 - 15) * 12 / 32 : 0;  // about +-6 levels
      auto c = [&](int v) { return std::clamp(v + offset, 0, 255); };
      out[i] = mapper.nearest(c(p[0]), c(p[1]), c(p[2]));
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------------------------
// GIF LZW (variable code size 9..12 bits, minimum code size 8)
// ---------------------------------------------------------------------------------------------------------------

struct BitWriter {
  std::vector<uint8_t>& out;
  uint32_t acc = 0;
  int nbits = 0;
  void put(int code, int size) {
    acc |= uint32_t(code) << nbits;
    nbits += size;
    for (; nbits >= 8; nbits -= 8, acc >>= 8) out.push_back(uint8_t(acc & 255));
  }
  void flush() {
    if (nbits > 0) out.push_back(uint8_t(acc & 255));
    acc = 0, nbits = 0;
  }
};

// (prefix code, next index) -> code, open addressing; at most 4096 - 258 entries live at once.
struct LzwDict {
  static constexpr int kSize = 8192;
  std::vector<int32_t> keys = std::vector<int32_t>(kSize, -1);
  std::vector<int16_t> codes = std::vector<int16_t>(kSize, 0);
  static uint32_t slot(int32_t key) { return (uint32_t(key) * 2654435761u) >> 19; }
  int find(int prefix, int k) const {
    int32_t key = (prefix << 8) | k;
    for (uint32_t s = slot(key);; s = (s + 1) & (kSize - 1)) {
      if (keys[s] == key) return codes[s];
      if (keys[s] < 0) return -1;
    }
  }
  void insert(int prefix, int k, int code) {
    int32_t key = (prefix << 8) | k;
    uint32_t s = slot(key);
    while (keys[s] >= 0) s = (s + 1) & (kSize - 1);
    keys[s] = key, codes[s] = int16_t(code);
  }
  void reset() { std::fill(keys.begin(), keys.end(), -1); }
};

std::vector<uint8_t> lzw_encode(const std::vector<uint8_t>& idx) {
  const int clear = 256, eoi = 257;
  std::vector<uint8_t> out;
  BitWriter bits{out};
  LzwDict dict;
  int size = 9, max_code = eoi;
  bits.put(clear, size);
  int cur = idx[0];
  for (size_t i = 1; i < idx.size(); ++i) {
    int k = idx[i];
    int code = dict.find(cur, k);
    if (code >= 0) {
      cur = code;
      continue;
    }
    bits.put(cur, size);
    dict.insert(cur, k, ++max_code);
    // The decoder adds its entries one code later, so it widens exactly when our newest code needs the next bit.
    if (max_code >= (1 << size)) ++size;
    if (max_code == 4095) {  // table full: start over
      bits.put(clear, size);
      dict.reset();
      size = 9, max_code = eoi;
    }
    cur = k;
  }
  bits.put(cur, size);
  // Reading that last code makes the decoder add one more entry, which may widen its codes before the EOI.
  if (max_code + 1 >= (1 << size) && size < 12) ++size;
  bits.put(eoi, size);
  bits.flush();
  return out;
}

// ---------------------------------------------------------------------------------------------------------------
// GIF container
// ---------------------------------------------------------------------------------------------------------------

void put_u16(std::vector<uint8_t>& out, int v) {
  out.push_back(uint8_t(v & 255));
  out.push_back(uint8_t((v >> 8) & 255));
}

void put_sub_blocks(std::vector<uint8_t>& out, const std::vector<uint8_t>& data) {
  for (size_t i = 0; i < data.size(); i += 255) {
    size_t n = std::min<size_t>(255, data.size() - i);
    out.push_back(uint8_t(n));
    out.insert(out.end(), data.begin() + i, data.begin() + i + n);
  }
  out.push_back(0);
}

void put_gif_header(std::vector<uint8_t>& out, int w, int h, const std::vector<Colour>& palette, bool loop) {
  const char* sig = "GIF89a";
  out.insert(out.end(), sig, sig + 6);
  put_u16(out, w);
  put_u16(out, h);
  out.push_back(0xF7);  // global colour table, 8-bit colour resolution, 256 entries
  out.push_back(0);     // background colour index
  out.push_back(0);     // pixel aspect ratio: unspecified
  for (int i = 0; i < 256; ++i)
    for (int c = 0; c < 3; ++c) out.push_back(i < int(palette.size()) ? palette[i][c] : 0);
  if (loop) {
    const char* app = "NETSCAPE2.0";
    out.insert(out.end(), {0x21, 0xFF, 0x0B});
    out.insert(out.end(), app, app + 11);
    out.insert(out.end(), {0x03, 0x01, 0x00, 0x00, 0x00});  // loop count 0 = forever
  }
}

void put_gif_frame(std::vector<uint8_t>& out, int w, int h, int delay_cs, const std::vector<uint8_t>& indices) {
  out.insert(out.end(), {0x21, 0xF9, 0x04, 0x04});  // graphic control: disposal "leave in place", no transparency
  put_u16(out, delay_cs);
  out.insert(out.end(), {0x00, 0x00});
  out.push_back(0x2C);  // image descriptor: full frame, no local table, not interlaced
  put_u16(out, 0);
  put_u16(out, 0);
  put_u16(out, w);
  put_u16(out, h);
  out.push_back(0x00);
  out.push_back(8);  // LZW minimum code size
  put_sub_blocks(out, lzw_encode(indices));
}

}  // namespace

std::vector<Colour> gif_palette(const std::vector<torch::Tensor>& frames_hwc_u8) {
  auto frames = checked_video_frames("<palette>", frames_hwc_u8, 1.0);
  auto exact = exact_colours(frames);
  return exact.empty() ? median_cut(frames, 256) : exact;
}

void write_gif(const std::string& path, const std::vector<torch::Tensor>& frames_hwc_u8, double fps, bool loop,
               bool dither) {
  auto frames = checked_video_frames(path, frames_hwc_u8, fps);
  int h = int(frames[0].size(0)), w = int(frames[0].size(1));
  if (w > 65535 || h > 65535) throw std::runtime_error("gif '" + path + "': frames larger than 65535 pixels");
  auto palette = exact_colours(frames);
  bool exact = !palette.empty();
  if (!exact) palette = median_cut(frames, 256);
  ColourMapper mapper(palette, exact);
  int delay = std::max(1, int(std::lround(100.0 / fps)));
  std::vector<uint8_t> out;
  put_gif_header(out, w, h, palette, loop);
  for (const auto& f : frames) put_gif_frame(out, w, h, delay, index_frame(f, mapper, dither && !exact));
  out.push_back(0x3B);  // trailer
  write_file_atomic(path, out.data(), out.size());
}

}  // namespace uplvsm::io
