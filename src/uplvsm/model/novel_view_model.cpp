#include "uplvsm/model/novel_view_model.h"

#include "uplvsm/model/transformer.h"

namespace uplvsm::model {

TargetPoses resolve_target_poses(TargetPoses choice, const NovelViewModelImpl& model) {
  return choice == TargetPoses::Auto ? model.default_target_poses() : choice;
}

void keep(ForwardTrace* trace, std::initializer_list<std::pair<torch::Tensor ForwardTrace::*, torch::Tensor>> fields) {
  if (!trace) return;
  for (const auto& [field, value] : fields) trace->*field = value;
}

Views batch_of_one(const data::SceneViews& views, torch::Device device) {
  auto batched = [&](const torch::Tensor& t) { return t.defined() ? t.unsqueeze(0).to(device) : torch::Tensor(); };
  return {batched(views.images), batched(views.fxfycxcy), batched(views.c2w)};
}

const torch::Tensor& require_c2w(const Views& views, const char* which, TargetPoses source) {
  TORCH_CHECK(views.c2w.defined(), "target poses '", uplvsm::to_string(source), "' need the ", which,
              " views' cameras (c2w), which were not given");
  TORCH_CHECK(views.c2w.dim() == 4 && views.c2w.size(1) == views.images.size(1) && views.c2w.size(2) == 4 &&
                  views.c2w.size(3) == 4,
              which, " c2w must be [b, v, 4, 4] matching the images, got ", views.c2w.sizes());
  return views.c2w;
}

void NovelViewModelImpl::register_tokenizers() {
  auto image_tokenizer = register_module("image_tokenizer", std::make_shared<torch::nn::Module>());
  tokenizer = image_tokenizer->register_module("1", DinoTokenizer(config.dinov2, config.patch_size));
  target_pose_tokenizer =
      register_module("target_pose_tokenizer", PoseTokenizer(config.patch_size, config.transformer.d));
  canonical_pose_tokenizer =
      register_module("canonical_pose_tokenizer", PoseTokenizer(config.patch_size, config.transformer.d));
}

void NovelViewModelImpl::register_rgb_head() {
  image_token_decoder = register_module("image_token_decoder", RgbHead(config.transformer.d, config.patch_size));
  init_linear_weights(*target_pose_tokenizer, 0.02);
  init_linear_weights(*canonical_pose_tokenizer, 0.02);
  init_linear_weights(*image_token_decoder, 0.02);
}

torch::Tensor NovelViewModelImpl::tokenize(const torch::Tensor& images) {
  RECORD_FUNCTION("uplvsm::dinov2_tokenizer", std::vector<c10::IValue>());  // profiler spans (bench UPLVSM_PROFILE)
  const int64_t b = images.size(0), v = images.size(1);
  auto tokens = tokenizer(images.flatten(0, 1));
  return tokens.view({b, v, tokens.size(1), tokens.size(2)});
}

torch::Tensor NovelViewModelImpl::with_camera_tokens(const torch::Tensor& tokens, const torch::Tensor& rays) {
  const int64_t b = tokens.size(0), v = tokens.size(1), k = rays.size(1);
  auto marker = canonical_pose_tokenizer(rays.flatten(0, 1)).view({b, k, tokens.size(2), tokens.size(3)});
  if (k == v) return tokens + marker;
  // One split: its backward is one cat, where two slices zero-filled the whole gradient twice.
  auto marked_and_rest = tokens.split_with_sizes({k, v - k}, 1);
  return torch::cat({marked_and_rest[0] + marker, marked_and_rest[1]}, 1);
}

torch::Tensor NovelViewModelImpl::repeat_per_view(const torch::Tensor& x, int64_t views) {
  return x.unsqueeze(1).expand({-1, views, -1, -1}).reshape({x.size(0) * views, x.size(1), x.size(2)});
}

void NovelViewModelImpl::set_grad_checkpoint_every(int64_t k) {
  TORCH_CHECK(k >= 0, "grad_checkpoint_every must be >= 0, got ", k);
  grad_checkpoint_every = k;
  tokenizer->dino_vit->grad_checkpoint_every = k;
}

int64_t NovelViewModelImpl::parameter_count() const {
  int64_t total = 0;
  for (const auto& p : parameters()) total += p.numel();
  return total;
}

}  // namespace uplvsm::model
