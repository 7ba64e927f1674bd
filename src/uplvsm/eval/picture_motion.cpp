#include "uplvsm/eval/picture_motion.h"

#include <cmath>

namespace uplvsm::eval {

namespace F = torch::nn::functional;

namespace {

constexpr int64_t kWindow = 9;        // the flow's window, pixels
constexpr int kRefinements = 4;       // warped Lucas-Kanade steps: one alone under-reads steps past a pixel or two
constexpr double kMaxStep = 4.0;      // pixels: a flat pixel's unconstrained step must not fetch from far away
constexpr double kRegularise = 1e-4;  // of the mean structure-tensor trace: flat pixels stay finite

torch::Tensor box(const torch::Tensor& x) {
  return F::avg_pool2d(x, F::AvgPool2dFuncOptions(kWindow).stride(1).padding(kWindow / 2).count_include_pad(false));
}

// Central differences of [N, 1, H, W] along x and y, the border replicated.
std::pair<torch::Tensor, torch::Tensor> gradients(const torch::Tensor& x) {
  auto p = F::pad(x, F::PadFuncOptions({1, 1, 1, 1}).mode(torch::kReplicate));
  const int64_t H = x.size(2), W = x.size(3);
  auto gx = (p.narrow(2, 1, H).narrow(3, 2, W) - p.narrow(2, 1, H).narrow(3, 0, W)) / 2;
  auto gy = (p.narrow(2, 2, H).narrow(3, 1, W) - p.narrow(2, 0, H).narrow(3, 1, W)) / 2;
  return {gx, gy};
}

// x [N, 1, H, W] sampled at each pixel plus flow [N, 2, H, W], bilinear: it reproduces a linear ramp exactly, so it
// does not move the picture (the bicubic kernel of grid_sample, a = -0.75, shifts it by up to 0.05 px with the
// sub-pixel phase: a slide at 0.25 px per frame read as 0.20).
torch::Tensor warp(const torch::Tensor& x, const torch::Tensor& flow) {
  const int64_t H = x.size(2), W = x.size(3);
  auto opt = x.options();
  auto gx = (torch::arange(W, opt).view({1, 1, W}) + flow.select(1, 0)) * (2.0 / std::max<int64_t>(W - 1, 1)) - 1;
  auto gy = (torch::arange(H, opt).view({1, H, 1}) + flow.select(1, 1)) * (2.0 / std::max<int64_t>(H - 1, 1)) - 1;
  return F::grid_sample(
      x, torch::stack({gx, gy}, -1),
      F::GridSampleFuncOptions().mode(torch::kBilinear).padding_mode(torch::kBorder).align_corners(true));
}

}  // namespace

PictureMotion picture_motion(const torch::Tensor& frames) {
  TORCH_CHECK(frames.dim() == 4 && frames.size(0) >= 2, "picture_motion: expected frames [T >= 2, C, H, W], got ",
              frames.sizes());
  auto grey = frames.to(torch::kCPU, torch::kFloat64).mean(1, true);
  auto first = grey.slice(0, 0, -1), next = grey.slice(0, 1);
  auto flow = torch::zeros({first.size(0), 2, first.size(2), first.size(3)}, first.options());
  torch::Tensor weight;
  for (int i = 0; i < kRefinements; ++i) {
    auto moved = warp(next, flow);
    auto [gx, gy] = gradients((first + moved) / 2);  // the pair's mean: the step's estimate is symmetric in time
    auto dt = moved - first;
    auto sxx = box(gx * gx), sxy = box(gx * gy), syy = box(gy * gy);
    auto bx = box(gx * dt), by = box(gy * dt);
    const double eps = kRegularise * (sxx + syy).mean().item<double>() + 1e-30;
    auto a = sxx + eps, c = syy + eps, det = a * c - sxy * sxy;
    auto step = torch::cat({-(c * bx - sxy * by) / det, -(a * by - sxy * bx) / det}, 1);
    // The smaller eigenvalue: large only where the window has texture in two directions.
    weight = ((sxx + syy) / 2 - ((sxx - syy).pow(2) / 4 + sxy * sxy).sqrt()).clamp_min(0);
    // Each pixel's window sums its neighbours' residuals, each warped by its own flow: a badly determined pixel's
    // runaway step would corrupt them, so the flow is averaged over the window, weighted by how well it is known.
    flow = flow + step.clamp(-kMaxStep, kMaxStep);
    flow = box(flow * weight) / box(weight).clamp_min(1e-300);
  }
  return {flow, weight};
}

namespace {

torch::Tensor inner(const torch::Tensor& x) {
  const int64_t b = kMotionBorder;
  TORCH_CHECK(x.size(2) > 2 * b && x.size(3) > 2 * b, "picture motion: frames must be larger than ", 2 * b,
              " pixels each way, got ", x.sizes());
  return x.narrow(2, b, x.size(2) - 2 * b).narrow(3, b, x.size(3) - 2 * b);
}

double weighted_rms(const torch::Tensor& vectors, const torch::Tensor& weight) {
  const double total = weight.sum().item<double>();
  if (!(total > 1e-12)) return 0.0;
  return std::sqrt((vectors.pow(2).sum(1, true) * weight).sum().item<double>() / total);
}

}  // namespace

MotionChange motion_change(const torch::Tensor& frames) {
  TORCH_CHECK(frames.dim() == 4 && frames.size(0) >= 3, "temporal_wobble: expected frames [T >= 3, C, H, W], got ",
              frames.sizes());
  auto m = picture_motion(frames);
  auto flow = inner(m.flow), weight = inner(m.weight);
  weight = weight / weight.mean().clamp_min(1e-300);
  return {flow.slice(0, 1) - flow.slice(0, 0, -1), torch::minimum(weight.slice(0, 1), weight.slice(0, 0, -1))};
}

double temporal_wobble(const torch::Tensor& frames, const MotionChange& truth) {
  auto [change, weight] = motion_change(frames);
  TORCH_CHECK(truth.change.sizes() == change.sizes(), "temporal_wobble: the truth's motion ", truth.change.sizes(),
              " is not the frames' ", change.sizes());
  return weighted_rms(change - truth.change, torch::minimum(weight, truth.weight));
}

double temporal_wobble(const torch::Tensor& frames, const torch::Tensor& truth) {
  if (!truth.defined()) {
    auto [change, weight] = motion_change(frames);
    return weighted_rms(change, weight);
  }
  TORCH_CHECK(truth.sizes() == frames.sizes(), "temporal_wobble: the truth ", truth.sizes(),
              " is not the frames' shape ", frames.sizes());
  return temporal_wobble(frames, motion_change(truth));
}

double picture_speed(const torch::Tensor& frames) {
  auto m = picture_motion(frames);
  return weighted_rms(inner(m.flow), inner(m.weight));
}

}  // namespace uplvsm::eval
