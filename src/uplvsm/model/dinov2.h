// DINOv2 vision transformer (facebookresearch/dinov2 `DinoVisionTransformer`) with optional register tokens and the
// official UP-LVSM's extra RMSNorm QK-norm. Parameter names equal Meta's state_dict names (cls_token, pos_embed,
// register_tokens, patch_embed.proj, blocks.{i}.{norm1,attn.qkv,attn.proj,ls1.gamma,norm2,mlp.fc1,mlp.fc2,ls2.gamma},
// norm), so Meta's files and the official UP-LVSM's `image_tokenizer.1.dino_vit.*` tensors load directly.
#pragma once
#include <torch/torch.h>

#include "uplvsm/core/config.h"
#include "uplvsm/model/transformer.h"

namespace uplvsm::model {

struct DinoAttentionImpl : torch::nn::Module {
  DinoAttentionImpl(int64_t dim, int64_t heads, bool qk_norm, double qk_norm_eps);
  torch::Tensor forward(const torch::Tensor& x);
  Linear qkv{nullptr}, proj{nullptr};
  RMSNorm q_norm{nullptr}, k_norm{nullptr};  // only with qk_norm
  int64_t heads;
};
TORCH_MODULE(DinoAttention);

struct DinoMlpImpl : torch::nn::Module {
  DinoMlpImpl(int64_t dim, int64_t hidden, int64_t out);
  torch::Tensor forward(const torch::Tensor& x);
  Linear fc1{nullptr}, fc2{nullptr};
};
TORCH_MODULE(DinoMlp);

struct LayerScaleImpl : torch::nn::Module {
  LayerScaleImpl(int64_t dim, double init);
  torch::Tensor forward(const torch::Tensor& x) { return x * gamma; }
  torch::Tensor gamma;
};
TORCH_MODULE(LayerScale);

struct DinoBlockImpl : torch::nn::Module {
  DinoBlockImpl(const Dinov2Config& c);
  // x = x + ls1(attn(norm1(x))); x = x + ls2(mlp(norm2(x))). The reference; Dinov2 runs its blocks through the
  // layer loop (layer_loop.h), which reads a block as layers().
  torch::Tensor forward(const torch::Tensor& x);
  BlockLayers layers();
  LayerNorm norm1{nullptr}, norm2{nullptr};
  DinoAttention attn{nullptr};
  LayerScale ls1{nullptr}, ls2{nullptr};
  DinoMlp mlp{nullptr};
};
TORCH_MODULE(DinoBlock);

struct DinoFeatures {
  torch::Tensor cls;           // [N, D] after the final norm
  torch::Tensor patch_tokens;  // [N, h*w, D] after the final norm, row-major patch order
  torch::Tensor prenorm;       // [N, 1 + R + h*w, D] before the final norm
};

// MAE's fixed-scale 2-D sine-cosine position table, [1, 1 + grid*grid, dim] in row-major patch order: channels
// [sin x, cos x, sin y, cos y] at frequencies 10000^(-k/(dim/4)); the class token's row is zero. dim % 4 == 0.
torch::Tensor sincos_pos_embed(int64_t grid, int64_t dim);

struct Dinov2Impl : torch::nn::Module {
  Dinov2Impl(const Dinov2Config& c, int64_t patch_size);
  // x: [N, 3, H, W] (already normalised as the caller wants). H, W multiples of the patch size. With `mask`
  // (bool [N, h*w], true: hidden) the patch embeddings it marks are replaced by `mask_token` [D] before the position
  // embedding, as DINOv2's prepare_tokens_with_masks does for its masked-image objective.
  DinoFeatures forward_features(const torch::Tensor& x, const torch::Tensor& mask = {},
                                const torch::Tensor& mask_token = {});
  torch::Tensor forward(const torch::Tensor& x) { return forward_features(x).patch_tokens; }
  // pos_embed resized to an (H/p) x (W/p) grid exactly as the official interpolate_pos_encoding: [1, 1 + h*w, D].
  torch::Tensor interpolate_pos_encoding(int64_t height, int64_t width);

  Dinov2Config config;
  int64_t patch_size;
  torch::Tensor cls_token, pos_embed, register_tokens;
  torch::nn::Conv2d patch_embed_proj{nullptr};
  torch::nn::ModuleList blocks{nullptr};
  LayerNorm norm{nullptr};
  int64_t grad_checkpoint_every = 0;  // blocks per checkpointed group when training (0: off)

  // The blocks in order, through the layer loop.
  torch::Tensor run_blocks(torch::Tensor tokens);
};
TORCH_MODULE(Dinov2);

// The image tokenizer of UP-LVSM: images in [0, 1] -> DINOv2 patch tokens [N, n, D]. Optional ImageNet
// normalisation (off in the official UP-LVSM). Holds the ViT as child "dino_vit" (official key prefix).
struct DinoTokenizerImpl : torch::nn::Module {
  DinoTokenizerImpl(const Dinov2Config& c, int64_t patch_size);
  torch::Tensor forward(const torch::Tensor& images01);
  // The same with masked patches (Dinov2Impl::forward_features): the masked-image pretraining stage.
  torch::Tensor forward_masked(const torch::Tensor& images01, const torch::Tensor& mask,
                               const torch::Tensor& mask_token);
  Dinov2 dino_vit{nullptr};
  bool imagenet_normalize;
};
TORCH_MODULE(DinoTokenizer);

}  // namespace uplvsm::model
