#include "uplvsm/serve/viewer_model.h"

#include <stdexcept>

#include "uplvsm/core/autocast.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/model/encoded_scene.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/pose_mapper.h"
#include "uplvsm/model/pose_mapper_file.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::serve {

PoseSpace parse_pose_space(const std::string& name) {
  if (name == "latent") return PoseSpace::Latent;
  if (name == "real") return PoseSpace::Real;
  throw std::invalid_argument("space must be \"latent\" or \"real\", got \"" + name + "\"");
}

const char* to_string(PoseSpace space) { return space == PoseSpace::Latent ? "latent" : "real"; }

int64_t SceneEncoding::bytes() const {
  auto size = [](const torch::Tensor& t) {
    return t.defined() ? t.numel() * static_cast<int64_t>(t.element_size()) : 0;
  };
  return size(latents) + size(key_latent) + size(key_real) + size(fxfycxcy);
}

ViewerModel ViewerModel::load(const std::string& checkpoint, const std::string& config_hint, torch::Device device,
                              bool bf16, const std::string& mapper) {
  Config config;
  auto net = model::load_model_with_config_file(checkpoint, config_hint, device, &config);
  // The viewer starts from unposed photos: only UP-LVSM renders those (the posed models need input cameras).
  auto up = model::require_uplvsm(net, "serve (the viewer starts from unposed photos)");
  if (!mapper.empty()) model::attach_pose_mapper_file(*up, mapper);
  return ViewerModel(up.ptr(), config, bf16);
}

ViewerModel::ViewerModel(std::shared_ptr<model::UPLVSMImpl> net, Config config, bool bf16)
    : net_(std::move(net)), config_(std::move(config)), bf16_(bf16) {
  net_->eval();
  auto params = net_->parameters();
  if (!params.empty()) device_ = params.front().device();
}

bool ViewerModel::has_mapper() const { return static_cast<bool>(net_->pose_mapper); }

int64_t ViewerModel::parameter_count() const { return net_->parameter_count(); }

// Photos carry no cameras: input 0 is the origin of camera-control units and input 1 one baseline from it, so only
// input 1's pose is unknown; it is solved through the mapper (model::invert_pose_mapper, a convergent least-squares
// solve with its residual) so that rendering there gives the latent pose the estimator read from that photo.
void ViewerModel::place_second_photo(SceneEncoding& s) const {
  auto& mapper = *net_->pose_mapper;
  auto inverse = model::invert_pose_mapper(mapper, s.key_latent[1],
                                           mapper.reads_scene() ? model::mapper_conditioning(s) : torch::Tensor());
  auto origin = torch::tensor({0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}, torch::kFloat64);
  s.key_real = torch::stack({origin, inverse.real});
  s.key_real_residual = inverse.residual;
  s.key_real_estimated = true;
}

SceneEncoding ViewerModel::encode(const data::SceneViews& views, bool posed) const {
  TORCH_CHECK(views.images.dim() == 4 && views.images.size(0) == 2 && views.images.size(1) == 3,
              "serve: a scene is two views [2, 3, H, W], got ", views.images.sizes());
  torch::NoGradGuard no_grad;
  SceneEncoding s;
  {
    Bf16Autocast amp(device_, bf16_);  // the model only: the mapper's inversion below needs fp32 Jacobians
    static_cast<model::EncodedScene&>(s) = model::encode_scene(*net_, views.images, views.fxfycxcy.to(torch::kFloat32));
    s.key_latent = s.input_poses.to(torch::kCPU, torch::kFloat64);
  }
  s.fxfycxcy = views.fxfycxcy[0].to(torch::kCPU, torch::kFloat32).clone();
  if (has_mapper()) {
    if (posed && views.c2w.defined()) {
      auto c2w = views.c2w.unsqueeze(0);
      s.key_real = geometry::camera_control_poses(c2w, c2w)[0].to(torch::kFloat64);
    } else {
      place_second_photo(s);
    }
  }
  return s;
}

torch::Tensor ViewerModel::render(const SceneEncoding& scene, const torch::Tensor& poses, PoseSpace space) const {
  TORCH_CHECK(poses.dim() == 2 && poses.size(1) == 7, "serve: poses must be [F, 7], got ", poses.sizes());
  if (space == PoseSpace::Real && !has_mapper())
    throw std::invalid_argument("this checkpoint has no camera mapper: render latent poses (space \"latent\")");
  Bf16Autocast amp(device_, bf16_);
  auto latent =
      space == PoseSpace::Real ? model::latent_poses_of_cameras(*net_, scene, poses) : poses.to(torch::kFloat32);
  auto k = scene.fxfycxcy.view({1, 4}).expand({poses.size(0), 4}).contiguous();
  return model::render_latent_poses(*net_, scene, latent, k);
}

}  // namespace uplvsm::serve
