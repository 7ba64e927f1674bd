// Official preprocessing and camera row conversions; the resize reproduces Pillow's Resample.c (8-bit path).
#include "uplvsm/data/preprocess.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "uplvsm/io/image.h"

namespace uplvsm::data {
namespace {

constexpr int kPrecisionBits = 32 - 8 - 2;  // Pillow's PRECISION_BITS: 8 bits of result, 2 of headroom

double sinc(double x) {
  if (x == 0.0) return 1.0;
  x = x * M_PI;
  return std::sin(x) / x;
}

double lanczos3(double x) { return (-3.0 <= x && x < 3.0) ? sinc(x) * sinc(x / 3) : 0.0; }

// Filter taps of one resampling direction: for output i, input indices [start[i], start[i]+count[i]) with
// weights[i*ksize + j], already quantised to kPrecisionBits fixed point.
struct Taps {
  int ksize = 0;
  std::vector<int> start, count;
  std::vector<int32_t> weights;
};

// Pillow's precompute_coeffs + normalize_coeffs_8bpc for the box [0, in_size] (the default box of resize()).
Taps lanczos_taps(int in_size, int out_size) {
  const double support_base = 3.0;
  double scale = static_cast<double>(static_cast<float>(in_size) - 0.0f) / out_size;
  double filterscale = scale < 1.0 ? 1.0 : scale;
  double support = support_base * filterscale;
  Taps taps;
  taps.ksize = static_cast<int>(std::ceil(support)) * 2 + 1;
  taps.start.resize(out_size);
  taps.count.resize(out_size);
  taps.weights.assign(static_cast<size_t>(out_size) * taps.ksize, 0);
  std::vector<double> k(taps.ksize);
  for (int xx = 0; xx < out_size; ++xx) {
    double center = 0.0 + (xx + 0.5) * scale;
    double ss = 1.0 / filterscale;
    int xmin = std::max(static_cast<int>(center - support + 0.5), 0);  // (int) truncates, as in C
    int xmax = std::min(static_cast<int>(center + support + 0.5), in_size) - xmin;
    double ww = 0.0;
    for (int x = 0; x < xmax; ++x) {
      k[x] = lanczos3((x + xmin - center + 0.5) * ss);
      ww += k[x];
    }
    for (int x = 0; x < xmax; ++x) {
      double w = ww != 0.0 ? k[x] / ww : k[x];
      taps.weights[static_cast<size_t>(xx) * taps.ksize + x] =
          static_cast<int32_t>(w < 0 ? (-0.5 + w * (1 << kPrecisionBits)) : (0.5 + w * (1 << kPrecisionBits)));
    }
    taps.start[xx] = xmin;
    taps.count[xx] = xmax;
  }
  return taps;
}

inline uint8_t clip8(int32_t v) {
  int32_t s = v >> kPrecisionBits;  // arithmetic shift, as Pillow's lookup index
  return static_cast<uint8_t>(s < 0 ? 0 : (s > 255 ? 255 : s));
}

// Horizontal pass over input rows [row0, row0+rows): in [H,W,3] -> out [rows, out_w, 3].
void resample_horizontal(const uint8_t* in, int in_w, int row0, int rows, const Taps& taps, int out_w, uint8_t* out) {
  for (int y = 0; y < rows; ++y) {
    const uint8_t* src = in + static_cast<size_t>(row0 + y) * in_w * 3;
    uint8_t* dst = out + static_cast<size_t>(y) * out_w * 3;
    for (int xx = 0; xx < out_w; ++xx) {
      const int32_t* k = &taps.weights[static_cast<size_t>(xx) * taps.ksize];
      const uint8_t* p = src + static_cast<size_t>(taps.start[xx]) * 3;
      int32_t s0 = 1 << (kPrecisionBits - 1), s1 = s0, s2 = s0;
      for (int x = 0; x < taps.count[xx]; ++x) {
        s0 += p[x * 3 + 0] * k[x];
        s1 += p[x * 3 + 1] * k[x];
        s2 += p[x * 3 + 2] * k[x];
      }
      dst[xx * 3 + 0] = clip8(s0);
      dst[xx * 3 + 1] = clip8(s1);
      dst[xx * 3 + 2] = clip8(s2);
    }
  }
}

// Vertical pass: in [*, w, 3] (rows already offset by row_shift) -> out [out_h, w, 3].
void resample_vertical(const uint8_t* in, int w, int row_shift, const Taps& taps, int out_h, uint8_t* out) {
  const size_t stride = static_cast<size_t>(w) * 3;
  for (int yy = 0; yy < out_h; ++yy) {
    const int32_t* k = &taps.weights[static_cast<size_t>(yy) * taps.ksize];
    const uint8_t* col = in + static_cast<size_t>(taps.start[yy] - row_shift) * stride;
    uint8_t* dst = out + static_cast<size_t>(yy) * stride;
    for (size_t c = 0; c < stride; ++c) {
      int32_t s = 1 << (kPrecisionBits - 1);
      for (int y = 0; y < taps.count[yy]; ++y) s += col[y * stride + c] * k[y];
      dst[c] = clip8(s);
    }
  }
}

// Python 3 round(): nearest, ties to even.
int64_t python_round(double x) {
  double f = std::floor(x);
  double diff = x - f;
  if (diff > 0.5) return static_cast<int64_t>(f) + 1;
  if (diff < 0.5) return static_cast<int64_t>(f);
  return static_cast<int64_t>(f) % 2 == 0 ? static_cast<int64_t>(f) : static_cast<int64_t>(f) + 1;
}

// One frame: resize + crop -> float [3,s,s]; writes the rescaled, shifted intrinsics into fxfycxcy[0..3].
torch::Tensor preprocess_frame(const torch::Tensor& frame, const float* cam, const PreprocessOptions& opt,
                               double* fxfycxcy) {
  int h0 = static_cast<int>(frame.size(0)), w0 = static_cast<int>(frame.size(1));
  int hr = opt.image_size;
  int wr = resized_width(h0, w0, opt.image_size, opt.patch_size);
  torch::Tensor resized = resize_lanczos_pil(frame, wr, hr);
  int start_w = 0, start_h = 0;
  if (opt.square_crop) {
    int side = std::min(hr, wr);
    start_w = (wr - side) / 2;
    start_h = (hr - side) / 2;
    resized = resized.slice(0, start_h, start_h + side).slice(1, start_w, start_w + side);
  }
  // Pixels of the original image first (normalised * W0 or H0), then scaled by the resize ratios, then shifted.
  double sx = static_cast<double>(wr) / w0, sy = static_cast<double>(hr) / h0;
  fxfycxcy[0] = static_cast<double>(cam[0]) * w0 * sx;
  fxfycxcy[1] = static_cast<double>(cam[1]) * h0 * sy;
  fxfycxcy[2] = static_cast<double>(cam[2]) * w0 * sx - start_w;
  fxfycxcy[3] = static_cast<double>(cam[3]) * h0 * sy - start_h;
  return io::to_float_chw(resized.contiguous());
}

}  // namespace

std::pair<int, int> preprocessed_size(int height, int width, const PreprocessOptions& opt) {
  const int wr = resized_width(height, width, opt.image_size, opt.patch_size);
  if (!opt.square_crop) return {opt.image_size, wr};
  const int side = std::min(opt.image_size, wr);
  return {side, side};
}

int resized_width(int height, int width, int image_size, int patch_size) {
  if (height <= 0 || width <= 0 || image_size <= 0 || patch_size <= 0)
    throw std::runtime_error(fmt::format("resized_width: bad sizes (image {}x{}, image_size {}, patch {})", height,
                                         width, image_size, patch_size));
  double scaled = static_cast<double>(image_size) / height * width;  // Python: Hr / H0 * W0
  auto truncated = static_cast<int64_t>(scaled);                     // int()
  int64_t wr = python_round(static_cast<double>(truncated) / patch_size) * patch_size;
  if (wr <= 0)
    throw std::runtime_error(
        fmt::format("resized_width: image {}x{} at {} rows rounds to width 0", height, width, image_size));
  return static_cast<int>(wr);
}

torch::Tensor resize_lanczos_pil(const torch::Tensor& hwc_u8, int out_w, int out_h) {
  if (!hwc_u8.defined() || hwc_u8.scalar_type() != torch::kUInt8 || hwc_u8.dim() != 3 || hwc_u8.size(2) != 3)
    throw std::runtime_error("resize_lanczos_pil: expected a uint8 tensor [H,W,3]");
  if (out_w <= 0 || out_h <= 0)
    throw std::runtime_error(fmt::format("resize_lanczos_pil: bad output size {}x{}", out_w, out_h));
  auto in = hwc_u8.contiguous();
  int in_h = static_cast<int>(in.size(0)), in_w = static_cast<int>(in.size(1));
  bool need_h = out_w != in_w, need_v = out_h != in_h;
  if (!need_h && !need_v) return in.clone();
  Taps vert = lanczos_taps(in_h, out_h);
  // Like Pillow, the horizontal pass only covers the source rows the vertical pass will read.
  int row_first = vert.start.front();
  int row_last = vert.start.back() + vert.count.back();
  torch::Tensor mid = in;
  int row_shift = 0;
  if (need_h) {
    Taps horiz = lanczos_taps(in_w, out_w);
    int rows = need_v ? row_last - row_first : in_h;
    int row0 = need_v ? row_first : 0;
    mid = torch::empty({rows, out_w, 3}, torch::kUInt8);
    resample_horizontal(in.data_ptr<uint8_t>(), in_w, row0, rows, horiz, out_w, mid.data_ptr<uint8_t>());
    row_shift = row0;
  }
  if (!need_v) return mid;
  auto out = torch::empty({out_h, mid.size(1), 3}, torch::kUInt8);
  resample_vertical(mid.data_ptr<uint8_t>(), static_cast<int>(mid.size(1)), row_shift, vert, out_h,
                    out.data_ptr<uint8_t>());
  return out;
}

void check_cameras(const torch::Tensor& cameras18, const std::string& what) {
  if (!cameras18.defined() || cameras18.dim() != 2 || cameras18.size(1) != 18 || !cameras18.is_floating_point())
    throw std::runtime_error(
        fmt::format("{}: field 'cameras' must be a float tensor [N,18], got {}", what,
                    cameras18.defined() ? c10::str(cameras18.scalar_type(), cameras18.sizes()) : "undefined"));
  auto finite = torch::isfinite(cameras18).all(1);
  if (!finite.all().item<bool>()) {
    int64_t frame = torch::nonzero(finite.logical_not()).select(1, 0)[0].item<int64_t>();
    auto row = cameras18[frame].to(torch::kFloat64).contiguous();
    std::vector<double> values(row.data_ptr<double>(), row.data_ptr<double>() + 18);
    throw std::runtime_error(
        fmt::format("{}: field 'cameras' has a NaN/Inf value in frame {}: [{}]", what, frame, fmt::join(values, ", ")));
  }
}

torch::Tensor cameras_to_c2w(const torch::Tensor& cameras18, const std::string& what) {
  check_cameras(cameras18, what);
  int64_t n = cameras18.size(0);
  auto w2c = torch::eye(4, torch::kFloat64).repeat({n, 1, 1});
  w2c.slice(1, 0, 3).copy_(cameras18.slice(1, 6, 18).to(torch::kFloat64).reshape({n, 3, 4}));
  auto [c2w, info] = torch::linalg_inv_ex(w2c);
  auto bad = torch::nonzero(info != 0);
  if (bad.numel() > 0)
    throw std::runtime_error(fmt::format("{}: field 'cameras' has a singular world-to-camera matrix in frame {}", what,
                                         bad[0][0].item<int64_t>()));
  return c2w.to(torch::kFloat32);
}

torch::Tensor cameras_to_fxfycxcy(const torch::Tensor& cameras18, int width, int height) {
  auto k = cameras18.slice(1, 0, 4).to(torch::kFloat64);
  auto scale = torch::tensor({static_cast<double>(width), static_cast<double>(height), static_cast<double>(width),
                              static_cast<double>(height)},
                             torch::kFloat64);
  return (k * scale).to(torch::kFloat32);
}

torch::Tensor make_cameras18(const torch::Tensor& fxfycxcy_px, const torch::Tensor& w2c, int width, int height) {
  if (fxfycxcy_px.dim() != 2 || fxfycxcy_px.size(1) != 4 || w2c.dim() != 3 || w2c.size(0) != fxfycxcy_px.size(0) ||
      w2c.size(2) != 4 || (w2c.size(1) != 3 && w2c.size(1) != 4))
    throw std::runtime_error(fmt::format("make_cameras18: expected intrinsics [N,4] and w2c [N,3|4,4], got {} and {}",
                                         c10::str(fxfycxcy_px.sizes()), c10::str(w2c.sizes())));
  int64_t n = fxfycxcy_px.size(0);
  auto scale = torch::tensor({1.0 / width, 1.0 / height, 1.0 / width, 1.0 / height}, torch::kFloat64);
  auto rows = torch::zeros({n, 18}, torch::kFloat64);
  rows.slice(1, 0, 4).copy_(fxfycxcy_px.to(torch::kFloat64) * scale);
  rows.slice(1, 6, 18).copy_(w2c.to(torch::kFloat64).slice(1, 0, 3).reshape({n, 12}));
  return rows.to(torch::kFloat32);
}

SceneViews preprocess(const std::vector<torch::Tensor>& hwc_u8_frames, const torch::Tensor& cameras18,
                      const PreprocessOptions& opt, const std::string& what) {
  int64_t v = static_cast<int64_t>(hwc_u8_frames.size());
  check_cameras(cameras18, what);
  if (cameras18.size(0) != v)
    throw std::runtime_error(fmt::format("{}: {} frames but {} camera rows", what, v, cameras18.size(0)));
  if (v == 0) throw std::runtime_error(fmt::format("{}: no frames to preprocess", what));
  auto cams = cameras18.to(torch::kFloat32).contiguous();
  std::vector<torch::Tensor> images(v);
  std::vector<double> k(static_cast<size_t>(v) * 4);
  for (int64_t i = 0; i < v; ++i) {
    const auto& f = hwc_u8_frames[i];
    if (!f.defined() || f.scalar_type() != torch::kUInt8 || f.dim() != 3 || f.size(2) != 3)
      throw std::runtime_error(fmt::format("{}: view {} is not a uint8 [H,W,3] image", what, i));
    images[i] = preprocess_frame(f, cams.data_ptr<float>() + i * 18, opt, &k[i * 4]);
    if (images[i].sizes() != images[0].sizes())
      throw std::runtime_error(
          fmt::format("{}: view {} preprocesses to {} but view 0 to {} (frames of different "
                      "sizes {} vs {})",
                      what, i, c10::str(images[i].sizes()), c10::str(images[0].sizes()), c10::str(f.sizes()),
                      c10::str(hwc_u8_frames[0].sizes())));
  }
  SceneViews views;
  views.images = torch::stack(images);
  views.fxfycxcy = torch::from_blob(k.data(), {v, 4}, torch::kFloat64).to(torch::kFloat32);
  views.c2w = cameras_to_c2w(cams, what);
  views.frames.resize(v);
  for (int64_t i = 0; i < v; ++i) views.frames[i] = i;
  return views;
}

SceneViews preprocess_photo(const torch::Tensor& hwc_u8, double fov_deg, const PreprocessOptions& opt,
                            const std::string& what) {
  if (!(fov_deg > 0 && fov_deg < 180))
    throw std::runtime_error(fmt::format("{}: field of view must be in (0, 180) degrees, got {:g}", what, fov_deg));
  const double W = static_cast<double>(hwc_u8.size(1)), H = static_cast<double>(hwc_u8.size(0));
  const double fx_norm = 0.5 / std::tan(fov_deg * M_PI / 360.0);
  auto cam = torch::zeros({1, 18});
  cam[0][0] = fx_norm;
  cam[0][1] = fx_norm * W / H;  // square pixels
  cam[0][2] = 0.5;
  cam[0][3] = 0.5;
  for (int i = 0; i < 3; ++i) cam[0][6 + 5 * i] = 1.0;  // identity w2c
  return preprocess({hwc_u8}, cam, opt, what);
}

PreprocessOptions preprocess_options(const Config& config) {
  return {static_cast<int>(config.model.image_size), static_cast<int>(config.model.patch_size),
          config.dataset.square_crop};
}

PreprocessOptions square_preprocess_options(const Config& config) {
  auto square = preprocess_options(config);
  square.square_crop = true;
  return square;
}

}  // namespace uplvsm::data
