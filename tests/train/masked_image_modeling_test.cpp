// Masked image modelling (the tokenizer's self-supervised stage) against direct computations: the mask, the masked
// tokenizer, the per-patch normalised target and the loss.
#include <gtest/gtest.h>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/train/masked_image_modeling.h"

using namespace uplvsm;

TEST(MaskedImageModeling, RandomMaskHidesExactlyTheRatioPerImageAndVaries) {
  torch::manual_seed(0);
  auto mask = train::random_patch_mask(5, 36, 0.6);
  ASSERT_EQ(mask.sizes(), (std::vector<int64_t>{5, 36}));
  ASSERT_EQ(mask.scalar_type(), torch::kBool);
  for (int64_t i = 0; i < 5; ++i) EXPECT_EQ(mask[i].sum().item<int64_t>(), 22) << i;  // round(0.6 * 36)
  EXPECT_FALSE(torch::equal(mask[0], mask[1]));
  EXPECT_NE(test::error_of([] { train::random_patch_mask(1, 4, 1.0); }).find("mask ratio"), std::string::npos);
}

TEST(MaskedImageModeling, NormalizedPatchesMatchAPatchByPatchComputation) {
  torch::manual_seed(1);
  auto images = torch::rand({2, 3, 16, 24});
  auto got = train::normalized_patches(images, 8);
  ASSERT_EQ(got.sizes(), (std::vector<int64_t>{2, 6, 192}));
  for (int64_t n = 0; n < 2; ++n)
    for (int64_t r = 0; r < 2; ++r)
      for (int64_t c = 0; c < 3; ++c) {
        // (row, column, channel) order inside the patch, row-major patches.
        auto patch = images[n].slice(1, 8 * r, 8 * r + 8).slice(2, 8 * c, 8 * c + 8).permute({1, 2, 0}).reshape(-1);
        auto expected = (patch - patch.mean()) / (patch.var(/*unbiased=*/false) + 1e-6).sqrt();
        EXPECT_LT(test::max_abs_diff(got[n][3 * r + c], expected), 1e-5) << n << " " << r << " " << c;
      }
}

TEST(MaskedImageModeling, MaskedTokenizerReplacesOnlyTheHiddenPatchEmbeddings) {
  torch::manual_seed(2);
  train::MaskedImageModel mim(test::micro_model());
  mim->eval();
  auto images = torch::rand({2, 3, 32, 32});
  const int64_t n = 16;
  // Nothing hidden: exactly the plain tokenizer.
  auto none = torch::zeros({2, n}, torch::kBool);
  EXPECT_EQ(test::max_abs_diff(mim->tokenizer->forward_masked(images, none, mim->mask_token),
                               mim->tokenizer->forward(images)),
            0.0);
  // A hidden patch's embedding is the mask token: images that differ only inside the hidden patches give the same
  // tokens, and the visible ones do not change that.
  auto mask = torch::zeros({2, n}, torch::kBool);
  mask.index_put_({torch::indexing::Slice(), 5}, true);
  auto other = images.clone();
  other
      .index({torch::indexing::Slice(), torch::indexing::Slice(), torch::indexing::Slice(8, 16),
              torch::indexing::Slice(8, 16)})
      .uniform_();  // patch 5 = row 1, column 1
  EXPECT_LT(test::max_abs_diff(mim->tokenizer->forward_masked(images, mask, mim->mask_token),
                               mim->tokenizer->forward_masked(other, mask, mim->mask_token)),
            1e-6);
  EXPECT_GT(test::max_abs_diff(mim->tokenizer->forward(images), mim->tokenizer->forward(other)), 1e-4);
}

TEST(MaskedImageModeling, LossIsTheMeanSquaredErrorOverHiddenPatchesOnly) {
  torch::manual_seed(3);
  train::MaskedImageModel mim(test::micro_model());
  auto images = torch::rand({3, 3, 32, 32});
  auto mask = train::random_patch_mask(3, 16, 0.5);
  auto pred = mim->predict(images, mask);
  auto target = train::normalized_patches(images, 8);
  double sum = 0;
  int64_t count = 0;
  for (int64_t i = 0; i < 3; ++i)
    for (int64_t j = 0; j < 16; ++j)
      if (mask[i][j].item<bool>()) sum += (pred[i][j] - target[i][j]).pow(2).mean().item<double>(), ++count;
  EXPECT_NEAR(mim->forward(images, mask).item<double>(), sum / static_cast<double>(count), 1e-5);
}
