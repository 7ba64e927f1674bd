// uplvsm.metrics: PSNR, scikit-image-exact SSIM and LPIPS v0.1 on torch tensors (eval/metrics.h, eval/lpips.h).
#include <memory>

#include "binding_util.h"
#include "uplvsm/eval/lpips.h"
#include "uplvsm/eval/metrics.h"

namespace uplvsm::python {

namespace {

void check_pair(const torch::Tensor& pred, const torch::Tensor& gt, const char* where) {
  check_tensor(pred, where, "pred", {0, -1, -1, -1}, "[..., C, H, W]");
  check_tensor(gt, where, "gt", {0, -1, -1, -1}, "[..., C, H, W]");
  if (pred.sizes() != gt.sizes())
    throw py::value_error(std::string(where) + ": pred " + c10::str(pred.sizes()) + " and gt " + c10::str(gt.sizes()) +
                          " differ in shape");
}

// One LPIPS network with its weights, callable from several Python threads (the module is read-only in eval mode).
struct LpipsMetric {
  eval::Lpips net{nullptr};
  std::string name;
  torch::Tensor operator()(const torch::Tensor& pred, const torch::Tensor& gt) {
    check_pair(pred, gt, "lpips");
    if (pred.size(-3) != 3)
      throw py::value_error("lpips: expected RGB images [..., 3, H, W], got " + c10::str(pred.sizes()));
    py::gil_scoped_release release;
    torch::NoGradGuard no_grad;
    auto device = net->lin.front().device();
    return net->forward(pred.to(device, torch::kFloat32), gt.to(device, torch::kFloat32));
  }
};

std::shared_ptr<LpipsMetric> make_lpips(const std::string& backbone, const std::string& lin, const std::string& net,
                                        const py::object& device) {
  auto kind = [&] {
    try {
      return eval::parse_lpips_net(net);
    } catch (const std::exception& e) {
      throw py::value_error(e.what());
    }
  }();
  const auto dev = to_device(device);
  py::gil_scoped_release release;
  auto metric = std::make_shared<LpipsMetric>();
  metric->net = eval::load_lpips(kind, backbone, lin);
  metric->net->to(dev);
  metric->name = net;
  return metric;
}

}  // namespace

void bind_metrics(py::module_& root) {
  auto m = root.def_submodule("metrics", "Image-quality metrics with the community's exact definitions.");
  m.def(
      "psnr",
      [](const torch::Tensor& pred, const torch::Tensor& gt) {
        check_pair(pred, gt, "psnr");
        py::gil_scoped_release release;
        return eval::psnr(pred, gt);
      },
      py::arg("pred"), py::arg("gt"),
      R"(PSNR of image pairs pred, gt [..., C, H, W] (same shape, any float dtype, CPU or CUDA).

Both are clamped to [0, 1]; the MSE over (C, H, W) is computed in float64 and clamped below at 1e-10 (a perfect
prediction scores 100 dB). Returns float64 [...].)");
  m.def(
      "ssim",
      [](const torch::Tensor& pred, const torch::Tensor& gt) {
        check_pair(pred, gt, "ssim");
        py::gil_scoped_release release;
        return eval::ssim(pred, gt);
      },
      py::arg("pred"), py::arg("gt"),
      R"(SSIM exactly as scikit-image 0.19 computes it in pixelSplat-style evaluation code, without scikit-image:
structural_similarity(gt, pred, win_size=11, gaussian_weights=True, channel_axis=0, data_range=1.0) per image.

pred, gt: [..., C, H, W] with H, W >= 11, not clamped. float32 inputs follow skimage's float32 arithmetic, float64
inputs are computed in float64. Returns float64 [...].)");
  py::class_<LpipsMetric, std::shared_ptr<LpipsMetric>>(m, "LPIPS",
                                                        R"(LPIPS v0.1, as lpips.LPIPS(net=..., version='0.1')(x, y,
normalize=True) computes it, with weight files you give (nothing is downloaded).)")
      .def(py::init(&make_lpips), py::arg("backbone"), py::arg("lin"), py::arg("net") = "vgg",
           py::arg("device") = "cpu",
           R"(backbone: torchvision features weights of `net` (.pth or .safetensors, keys features.N.*).
lin: the official lpips lin weights (lpips/weights/v0.1/<net>.pth) or a safetensors copy (keys lin0..lin4).
net: "vgg" (default, the community's choice) or "alex". device: where it runs ("cpu", "cuda", a torch.device).)")
      .def("__call__", &LpipsMetric::operator(), py::arg("pred"), py::arg("gt"),
           "LPIPS of image pairs in [0, 1] [..., 3, H, W] (same shape). Returns float32 [...].")
      .def_readonly("net", &LpipsMetric::name)
      .def("__repr__", [](const LpipsMetric& l) { return "uplvsm.metrics.LPIPS(net='" + l.name + "')"; });
}

}  // namespace uplvsm::python
