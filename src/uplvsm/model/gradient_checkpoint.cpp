#include "uplvsm/model/gradient_checkpoint.h"

#include "uplvsm/core/autocast.h"

namespace uplvsm::model {
namespace {

using torch::autograd::AutogradContext;
using torch::autograd::variable_list;

// Carries the layer group into backward; an IValue capsule owns it, so it lives exactly as long as the graph node.
struct Recompute : torch::CustomClassHolder {
  LayerGroupFn fn;
  bool autocast = false;
};

struct CheckpointFunction : torch::autograd::Function<CheckpointFunction> {
  // Runs with grad mode off (Function::apply does that), so no activations are saved.
  static torch::Tensor forward(AutogradContext* ctx, torch::Tensor x, at::TensorList params, c10::IValue recompute) {
    ctx->save_for_backward({x});
    ctx->saved_data["recompute"] = recompute;
    ctx->saved_data["x_requires_grad"] = x.requires_grad();
    ctx->saved_data["params"] = c10::List<torch::Tensor>(params.vec());
    auto holder = c10::static_intrusive_pointer_cast<Recompute>(recompute.toCapsule());
    return holder->fn(x);
  }

  static variable_list backward(AutogradContext* ctx, variable_list grad_outputs) {
    auto holder = c10::static_intrusive_pointer_cast<Recompute>(ctx->saved_data["recompute"].toCapsule());
    const bool x_needs_grad = ctx->saved_data["x_requires_grad"].toBool();
    auto x = ctx->get_saved_variables()[0].detach().requires_grad_(x_needs_grad);
    auto params = ctx->saved_data["params"].toTensorList();  // the weights fn reads, for their gradients
    const size_t n_params = params.size();

    variable_list wrt;
    std::vector<size_t> slot;  // where each differentiated tensor's gradient goes in the result
    if (x_needs_grad) wrt.push_back(x), slot.push_back(0);
    for (size_t i = 0; i < n_params; ++i) {
      torch::Tensor p = params.get(i);
      if (p.requires_grad()) wrt.push_back(p), slot.push_back(i + 1);
    }
    variable_list result(n_params + 2);  // x, params..., the capsule (never differentiable)
    if (wrt.empty()) return result;

    torch::Tensor y;
    {
      torch::AutoGradMode grad_on(true);
      AutocastGuard autocast(x.device(), holder->autocast);
      y = holder->fn(x);
    }
    auto grads = torch::autograd::grad({y}, wrt, {grad_outputs[0]}, /*retain_graph=*/false,
                                       /*create_graph=*/false, /*allow_unused=*/true);
    for (size_t i = 0; i < grads.size(); ++i) result[slot[i]] = grads[i];
    return result;
  }
};

}  // namespace

torch::Tensor checkpointed(LayerGroupFn fn, const torch::Tensor& x, const std::vector<torch::Tensor>& params) {
  bool needs_grad = x.requires_grad();
  for (const auto& p : params) needs_grad = needs_grad || p.requires_grad();
  if (!torch::GradMode::is_enabled() || !needs_grad) return fn(x);
  auto holder = c10::make_intrusive<Recompute>();
  holder->fn = std::move(fn);
  holder->autocast = autocast_active(x.device());
  return CheckpointFunction::apply(x, at::TensorList(params), c10::IValue::make_capsule(holder));
}

}  // namespace uplvsm::model
