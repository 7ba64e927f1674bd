#include "uplvsm/model/dinov2.h"

#include <cmath>
#include <utility>

#include "uplvsm/kernels/ops.h"

namespace uplvsm::model {

using torch::indexing::Slice;

DinoAttentionImpl::DinoAttentionImpl(int64_t dim, int64_t heads_, bool qk_norm, double eps) : heads(heads_) {
  qkv = register_module("qkv", Linear(torch::nn::LinearOptions(dim, 3 * dim).bias(true)));
  proj = register_module("proj", Linear(torch::nn::LinearOptions(dim, dim).bias(true)));
  if (qk_norm) {
    q_norm = register_module("q_norm", RMSNorm(dim / heads, eps));
    k_norm = register_module("k_norm", RMSNorm(dim / heads, eps));
  }
}

torch::Tensor DinoAttentionImpl::forward(const torch::Tensor& x) {
  const auto no_norm = torch::Tensor();
  return proj(kernels::qk_norm_attention(qkv(x), heads, q_norm ? q_norm->weight : no_norm, q_norm ? q_norm->eps : 0,
                                         k_norm ? k_norm->weight : no_norm, k_norm ? k_norm->eps : 0));
}

DinoMlpImpl::DinoMlpImpl(int64_t dim, int64_t hidden, int64_t out) {
  fc1 = register_module("fc1", Linear(dim, hidden));
  fc2 = register_module("fc2", Linear(hidden, out));
}

LayerScaleImpl::LayerScaleImpl(int64_t dim, double init) {
  gamma = register_parameter("gamma", torch::full({dim}, init));
}

torch::Tensor DinoMlpImpl::forward(const torch::Tensor& x) { return fc2(kernels::gelu(fc1(x))); }

DinoBlockImpl::DinoBlockImpl(const Dinov2Config& c) {
  norm1 = register_module("norm1", LayerNorm(c.embed_dim, 1e-6, true));
  attn = register_module("attn", DinoAttention(c.embed_dim, c.num_heads, c.qk_norm, c.qk_norm_eps));
  ls1 = register_module("ls1", LayerScale(c.embed_dim, c.layerscale_init));
  norm2 = register_module("norm2", LayerNorm(c.embed_dim, 1e-6, true));
  mlp = register_module("mlp", DinoMlp(c.embed_dim, c.embed_dim * c.mlp_ratio, c.embed_dim));
  ls2 = register_module("ls2", LayerScale(c.embed_dim, c.layerscale_init));
}

torch::Tensor DinoBlockImpl::forward(const torch::Tensor& x) {
  const auto h = x + ls1(attn(norm1->forward_into_linear(x)));
  return h + ls2(mlp(norm2->forward_into_linear(h)));
}

BlockLayers DinoBlockImpl::layers() {
  BlockLayers l;
  l.block = shared_from_this();
  l.norm1 = norm1.ptr(), l.norm2 = norm2.ptr();
  l.qkv = attn->qkv.ptr(), l.proj = attn->proj.ptr(), l.heads = attn->heads;
  if (attn->q_norm) l.q_norm = attn->q_norm.ptr(), l.k_norm = attn->k_norm.ptr();
  l.fc1 = mlp->fc1.ptr(), l.fc2 = mlp->fc2.ptr();
  l.ls1 = ls1->gamma, l.ls2 = ls2->gamma;
  return l;
}

torch::Tensor sincos_pos_embed(int64_t grid, int64_t dim) {
  // MAE's 2-D table: a quarter of the channels each for sin/cos of x and of y at geometric frequencies; the class
  // token's row is zero.
  const int64_t q = dim / 4;
  auto omega = torch::pow(10000.0, -torch::arange(q, torch::kFloat64) / static_cast<double>(q));
  auto coord = torch::arange(grid, torch::kFloat64);
  auto x = coord.repeat({grid}).unsqueeze(1) * omega;           // column index of patch (row-major order)
  auto y = coord.repeat_interleave(grid).unsqueeze(1) * omega;  // row index
  auto table = torch::cat({torch::sin(x), torch::cos(x), torch::sin(y), torch::cos(y)}, 1);
  return torch::cat({torch::zeros({1, dim}, torch::kFloat64), table}, 0).unsqueeze(0).to(torch::kFloat32);
}

Dinov2Impl::Dinov2Impl(const Dinov2Config& c, int64_t patch) : config(c), patch_size(patch) {
  const int64_t D = c.embed_dim;
  cls_token = register_parameter("cls_token", torch::randn({1, 1, D}) * 1e-6);
  pos_embed = register_parameter(
      "pos_embed", c.pos_embed_init == "sincos"
                       ? sincos_pos_embed(c.pos_grid, D)
                       : trunc_normal_(torch::empty({1, 1 + c.pos_grid * c.pos_grid, D}), 0.0, 0.02, -2.0, 2.0));
  if (c.num_register_tokens > 0)
    register_tokens = register_parameter("register_tokens", torch::randn({1, c.num_register_tokens, D}) * 1e-6);
  auto patch_embed = register_module("patch_embed", std::make_shared<torch::nn::Module>());
  patch_embed_proj =
      patch_embed->register_module("proj", torch::nn::Conv2d(torch::nn::Conv2dOptions(3, D, patch).stride(patch)));
  blocks = register_module("blocks", torch::nn::ModuleList());
  for (int64_t i = 0; i < c.depth; ++i) blocks->push_back(DinoBlock(c));
  norm = register_module("norm", LayerNorm(D, 1e-6, true));
  // The official DINOv2's init (vision_transformer.py:176-181, 343-348 at d490397): pos_embed and every linear
  // trunc_normal_(std=0.02) with its absolute bounds -2 and 2, which cut nothing; zero biases. The paper's configs
  // replace it with Meta's pretrained weights (--init).
  torch::NoGradGuard no_grad;
  for (auto& m : blocks->modules()) {
    if (auto* lin = m->as<torch::nn::Linear>()) {
      trunc_normal_(lin->weight, 0.0, 0.02, -2.0, 2.0);
      lin->bias.zero_();
    }
  }
}

torch::Tensor Dinov2Impl::interpolate_pos_encoding(int64_t height, int64_t width) {
  const int64_t gh = height / patch_size, gw = width / patch_size;
  const int64_t M = config.pos_grid;
  if (gh == M && gw == M) return pos_embed;
  auto pe = pos_embed.to(torch::kFloat32);
  auto cls_pe = pe.index({Slice(), Slice(0, 1)});
  auto grid = pe.index({Slice(), Slice(1)}).reshape({1, M, M, -1}).permute({0, 3, 1, 2});
  namespace F = torch::nn::functional;
  auto opts =
      F::InterpolateFuncOptions().mode(torch::kBicubic).align_corners(false).antialias(config.interpolate_antialias);
  if (config.interpolate_offset != 0.0) {
    // Coordinates follow the given scale factor, not gh / M: reproduces the official 0.1-offset values.
    opts.scale_factor(std::vector<double>{(gh + config.interpolate_offset) / M, (gw + config.interpolate_offset) / M});
    opts.recompute_scale_factor(false);
  } else {
    opts.size(std::vector<int64_t>{gh, gw});
  }
  auto resized = F::interpolate(grid, opts);
  TORCH_CHECK(resized.size(2) == gh && resized.size(3) == gw, "DINOv2 pos-embed interpolation gave ", resized.sizes(),
              " for a ", gh, "x", gw, " grid");
  auto patches = resized.permute({0, 2, 3, 1}).reshape({1, gh * gw, -1});
  return torch::cat({cls_pe, patches}, 1).to(pos_embed.scalar_type());
}

torch::Tensor Dinov2Impl::run_blocks(torch::Tensor t) {
  std::vector<BlockLayers> layers;
  for (size_t i = 0; i < blocks->size(); ++i) layers.push_back(blocks->ptr<DinoBlockImpl>(i)->layers());
  return run_layers(layers, std::move(t), grad_checkpoint_every);
}

DinoFeatures Dinov2Impl::forward_features(const torch::Tensor& x, const torch::Tensor& mask,
                                          const torch::Tensor& mask_token) {
  const int64_t N = x.size(0), H = x.size(2), W = x.size(3);
  TORCH_CHECK(H % patch_size == 0 && W % patch_size == 0, "DINOv2: image ", H, "x", W,
              " is not a multiple of the patch size ", patch_size);
  auto t = patch_embed_proj(x).flatten(2).transpose(1, 2);  // [N, h*w, D]
  if (mask.defined()) {
    TORCH_CHECK(mask.dim() == 2 && mask.size(0) == N && mask.size(1) == t.size(1) && mask_token.numel() == t.size(2),
                "DINOv2: mask must be [N, ", t.size(1), "] with a [", t.size(2), "] mask token, got ", mask.sizes(),
                " and ", mask_token.sizes());
    t = torch::where(mask.unsqueeze(-1), mask_token.reshape({1, 1, -1}).to(t.dtype()), t);
  }
  t = torch::cat({cls_token.expand({N, -1, -1}), t}, 1) + interpolate_pos_encoding(H, W);
  const int64_t R = config.num_register_tokens;
  if (R > 0) {
    // One split: its backward is one cat, where two slices zero-filled the whole gradient twice.
    auto cls_and_patches = t.split_with_sizes({1, t.size(1) - 1}, 1);
    t = torch::cat({cls_and_patches[0], register_tokens.expand({N, -1, -1}), cls_and_patches[1]}, 1);
  }
  t = run_blocks(t);
  auto normed = norm(t);
  return {normed.select(1, 0), normed.index({Slice(), Slice(1 + R)}), t};
}

DinoTokenizerImpl::DinoTokenizerImpl(const Dinov2Config& c, int64_t patch_size)
    : imagenet_normalize(c.imagenet_normalize) {
  dino_vit = register_module("dino_vit", Dinov2(c, patch_size));
}

namespace {
torch::Tensor imagenet_normalized(const torch::Tensor& images01) {
  auto opts = images01.options();
  auto mean = torch::tensor({0.485, 0.456, 0.406}, opts).view({1, 3, 1, 1});
  auto std = torch::tensor({0.229, 0.224, 0.225}, opts).view({1, 3, 1, 1});
  return (images01 - mean) / std;
}
}  // namespace

torch::Tensor DinoTokenizerImpl::forward(const torch::Tensor& images01) {
  return dino_vit(imagenet_normalize ? imagenet_normalized(images01) : images01);
}

torch::Tensor DinoTokenizerImpl::forward_masked(const torch::Tensor& images01, const torch::Tensor& mask,
                                                const torch::Tensor& mask_token) {
  const auto x = imagenet_normalize ? imagenet_normalized(images01) : images01;
  return dino_vit->forward_features(x, mask, mask_token).patch_tokens;
}

}  // namespace uplvsm::model
