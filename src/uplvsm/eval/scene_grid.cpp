// The per-scene visualisation `uplvsm eval` writes: each target's prediction beside the inputs, the truth, an |error|
// heat map and the copy-nearest baseline, in one labelled grid (declared in evaluator.h).
#include <fmt/format.h>

#include <string>
#include <vector>

#include "uplvsm/eval/evaluator.h"
#include "uplvsm/io/raster.h"

namespace uplvsm::eval {

torch::Tensor error_heatmap(const torch::Tensor& pred, const torch::Tensor& gt, double gain) {
  // Anchors of an inferno-like ramp: black, purple, red, orange, pale yellow.
  static const std::vector<float> kAnchors = {0, 0, 4, 87, 16, 110, 188, 55, 84, 249, 142, 9, 252, 255, 164};
  const int64_t n = static_cast<int64_t>(kAnchors.size()) / 3;
  auto e = ((pred.to(torch::kFloat32) - gt.to(torch::kFloat32)).abs().mean(-3) * gain).clamp(0, 1);
  auto lut = torch::tensor(kAnchors).view({n, 3}).div(255.0).to(e.device());
  auto t = e * static_cast<double>(n - 1);
  auto i0 = t.floor().clamp(0, static_cast<double>(n - 2)).to(torch::kInt64);
  auto frac = (t - i0.to(torch::kFloat32)).unsqueeze(-1);
  auto out_shape = e.sizes().vec();
  out_shape.push_back(3);
  auto c0 = lut.index_select(0, i0.flatten()).view(out_shape);
  auto c1 = lut.index_select(0, (i0 + 1).flatten()).view(out_shape);
  return (c0 + (c1 - c0) * frac).movedim(-1, -3).contiguous();
}

torch::Tensor scene_grid(const SceneResult& scene, const torch::Tensor& inputs, const torch::Tensor& pred,
                         const torch::Tensor& gt, const torch::Tensor& copy) {
  auto cpu = [](const torch::Tensor& t) { return t.detach().to(torch::kCPU, torch::kFloat32); };
  auto in = cpu(inputs), p = cpu(pred), g = cpu(gt), c = cpu(copy);
  auto heat = error_heatmap(p, g);
  std::vector<std::string> cols;
  for (int64_t i = 0; i < in.size(0); ++i)
    cols.push_back(i < static_cast<int64_t>(scene.context.size())
                       ? fmt::format("input f{}", scene.context[static_cast<size_t>(i)])
                       : fmt::format("input {}", i));
  for (const char* label : {"prediction", "truth", "|error|x4", "copy nearest"}) cols.emplace_back(label);
  std::vector<std::vector<torch::Tensor>> rows;
  std::vector<std::string> row_labels;
  for (int64_t t = 0; t < p.size(0); ++t) {
    std::vector<torch::Tensor> row;
    for (int64_t i = 0; i < in.size(0); ++i) row.push_back(in[i]);
    row.insert(row.end(), {p[t], g[t], heat[t], c[t]});
    rows.push_back(std::move(row));
    if (t < static_cast<int64_t>(scene.views.size())) {
      const auto& v = scene.views[static_cast<size_t>(t)];
      row_labels.push_back(fmt::format("frame {}\n{:.2f} dB\nSSIM {:.3f}", v.frame, v.model.psnr, v.model.ssim));
    } else {
      row_labels.push_back(fmt::format("target {}", t));
    }
  }
  return io::make_grid(rows, row_labels, cols, /*pad=*/8);
}

}  // namespace uplvsm::eval
