#include "model_adapter.h"

#include <stdexcept>

#include "uplvsm/core/autocast.h"
#include "uplvsm/model/model_factory.h"

namespace uplvsm::python {

namespace {
// "none" | "bf16"; a bad value is the caller's argument error (ValueError in Python).
bool amp_enabled(const std::string& amp) {
  try {
    return parse_amp(amp) == Amp::Bf16;
  } catch (const std::runtime_error& e) {
    throw std::invalid_argument(e.what());
  }
}
}  // namespace

ModelAdapter::ModelAdapter(const std::string& path, const torch::Device& device, const Config* hint) : device_(device) {
  net_ = model::load_model(path, device, &config_, hint);
}

ModelAdapter::ModelAdapter(const Config& config, const torch::Device& device, uint64_t seed)
    : config_(config), device_(device) {
  torch::manual_seed(seed);
  net_ = model::make_model(config.model);
  net_->to(device);
  net_->eval();
}

int64_t ModelAdapter::parameter_count() const { return net_->parameter_count(); }

std::vector<std::pair<std::string, torch::Tensor>> ModelAdapter::state_dict() const {
  std::vector<std::pair<std::string, torch::Tensor>> out;
  for (const auto& p : net_->named_parameters(true)) out.emplace_back(p.key(), p.value().detach());
  for (const auto& b : net_->named_buffers(true)) out.emplace_back(b.key(), b.value().detach());
  return out;
}

model::UPLVSM ModelAdapter::unposed(const char* what) const {
  try {
    return model::require_uplvsm(net_, what);
  } catch (const c10::Error& e) {  // the caller asked the wrong model: an argument error (ValueError in Python)
    throw std::invalid_argument(std::string(e.what_without_backtrace()) + "; a " + net_->name() +
                                " model renders through forward or render_camera_path");
  }
}

torch::Tensor ModelAdapter::on_device(const torch::Tensor& t) const {
  return t.defined() ? t.to(device_, torch::kFloat32) : t;
}

torch::Tensor ModelAdapter::encode_scene(const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                         const std::string& amp) {
  auto net = unposed("encode_scene");
  Bf16Autocast guard(device_, amp_enabled(amp));
  return net->encode_scene(on_device(images), on_device(fxfycxcy));
}

torch::Tensor ModelAdapter::estimate_poses(const torch::Tensor& target_images, const torch::Tensor& scene_latents,
                                           const std::string& amp) {
  auto net = unposed("estimate_poses");
  Bf16Autocast guard(device_, amp_enabled(amp));
  return net->estimate_poses(on_device(target_images), scene_latents.to(device_));
}

torch::Tensor ModelAdapter::render_views(const torch::Tensor& scene_latents, const torch::Tensor& poses,
                                         const torch::Tensor& fxfycxcy, int64_t height, int64_t width,
                                         const std::string& amp) {
  auto net = unposed("render_views");
  Bf16Autocast guard(device_, amp_enabled(amp));
  return net->render_views(scene_latents.to(device_), on_device(poses), on_device(fxfycxcy), height, width);
}

ForwardResult ModelAdapter::forward(const model::Views& inputs, const model::Views& targets,
                                    const std::string& target_poses, const std::string& amp) {
  TargetPoses choice;
  try {
    choice = parse_target_poses(target_poses, "target_poses");
  } catch (const std::runtime_error& e) {
    throw std::invalid_argument(e.what());
  }
  const auto source = model::resolve_target_poses(choice, *net_);
  model::Views in{on_device(inputs.images), on_device(inputs.fxfycxcy), on_device(inputs.c2w)};
  model::Views out{on_device(targets.images), on_device(targets.fxfycxcy), on_device(targets.c2w)};
  Bf16Autocast guard(device_, amp_enabled(amp));
  auto result = net_->render(in, out, source);
  return {result.render, result.pose_enc};
}

render::InterpolationVideo ModelAdapter::render_interpolation(const torch::Tensor& images,
                                                              const torch::Tensor& fxfycxcy, int64_t num_frames,
                                                              int64_t chunk, const std::string& amp) {
  auto net = unposed("render_interpolation");
  Bf16Autocast guard(device_, amp_enabled(amp));
  return render::render_interpolation(net, images, fxfycxcy, num_frames, chunk);
}

torch::Tensor ModelAdapter::render_camera_path(const data::SceneViews& inputs, const torch::Tensor& poses,
                                               const torch::Tensor& fxfycxcy, int64_t chunk, const std::string& amp) {
  Bf16Autocast guard(device_, amp_enabled(amp));
  return render::render_camera_path(net_, inputs, poses, fxfycxcy, chunk);
}

}  // namespace uplvsm::python
