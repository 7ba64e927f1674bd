// The paper's cross-view attention figure: for one patch of input view 1, where the last encoder layer looks in
// input view 2 (that token's attention over view 2's tokens, mean over heads), beside the cosine similarity of the
// tokenizer (DINOv2) features, which shows what plain feature matching would pick.
#pragma once
#include <torch/torch.h>

#include <string>

#include "uplvsm/model/uplvsm.h"

namespace uplvsm::study {

struct CrossViewAttention {
  torch::Tensor attention;   // float [gh, gw]: the query patch's attention weights on view 2's patches
  torch::Tensor similarity;  // float [gh, gw]: cosine similarity of the tokenizer features, query vs view 2
  int64_t row = 0, col = 0;  // the query patch in view 1's patch grid
};

// images [2, 3, H, W] in [0, 1] and intrinsics [2, 4] (pixels) of the two input views; (row, col) a patch of view
// 1. UP-LVSM only (the encoder is what builds the scene latents); throws with the valid range otherwise.
CrossViewAttention cross_view_attention(model::UPLVSM& net, const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                        int64_t row, int64_t col);

// uint8 [H', W', 3]: view 1 with the query patch boxed | view 2 under the attention heat map | view 2 under the
// similarity heat map (each map stretched to its own min..max), panels scaled up to >= `panel` pixels wide.
torch::Tensor attention_figure(const torch::Tensor& images, const CrossViewAttention& result, int panel = 320);

// Heat map colours (dark blue -> cyan -> yellow -> red) of values in [0, 1]: float [3, h, w].
torch::Tensor heat_colours(const torch::Tensor& values);

}  // namespace uplvsm::study
