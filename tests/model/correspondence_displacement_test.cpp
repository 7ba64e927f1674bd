// model/correspondence_displacement against what it must find by construction: a target whose patches are view 0's
// shifted by whole patches, with sharp one-hot features, is displaced by exactly that shift; the readout starts at
// zero (the official estimator), and the estimator with it reads view 0's image tokens after the scene latents.
#include "uplvsm/model/correspondence_displacement.h"

#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/model/latent_plucker_learner.h"

using namespace uplvsm;
using namespace uplvsm::model;

TEST(CorrespondenceDisplacement, PatchGridIsRowMajorInTheUnitSquare) {
  auto grid = patch_grid(9, torch::TensorOptions());
  auto expected = torch::tensor({-2.0f / 3, -2.0f / 3, 0.0f, -2.0f / 3, 2.0f / 3, -2.0f / 3}).view({3, 2});
  EXPECT_LE(test::max_abs_diff(grid.narrow(0, 0, 3), expected), 1e-6);
  EXPECT_FLOAT_EQ(grid[3][1].item<float>(), 0.0f);  // the second row
  EXPECT_NE(test::error_of([] { patch_grid(10, torch::TensorOptions()); }).find("not a square grid"),
            std::string::npos);
}

TEST(CorrespondenceDisplacement, AShiftedImageIsDisplacedByItsShift) {
  // View 0: patch i carries feature e_i (one-hot, scaled so the softmax is a hard match). The target sees the
  // content one patch column to the right of where view 0 has it: target patch (r, c) holds view 0's (r, c + 1),
  // so its content is found one column (2 / side in grid units) to the right.
  const int64_t side = 4, n = side * side;
  auto keys = torch::eye(n).unsqueeze(0) * 40.0;
  auto queries = torch::zeros({1, n, n});
  for (int64_t r = 0; r < side; ++r)
    for (int64_t c = 0; c + 1 < side; ++c) queries[0][r * side + c][r * side + c + 1] = 40.0;
  auto displacement = correspondence_displacement(queries, keys, patch_grid(n, torch::TensorOptions()));
  for (int64_t r = 0; r < side; ++r)
    for (int64_t c = 0; c + 1 < side; ++c) {
      EXPECT_NEAR(displacement[0][r * side + c][0].item<float>(), 2.0 / side, 1e-4) << r << "," << c;
      EXPECT_NEAR(displacement[0][r * side + c][1].item<float>(), 0.0, 1e-4) << r << "," << c;
    }
}

TEST(CorrespondenceDisplacement, TheEstimatorStartsAsTheOfficialOneAndReadsViewZerosTokens) {
  TransformerConfig c;
  c.d = 32, c.d_head = 16, c.estimator_n_layer = 1, c.n_latent_vectors = 3;
  torch::manual_seed(2);
  LatentPluckerLearner official(c);
  c.estimator_correspondence = true;
  torch::manual_seed(2);
  LatentPluckerLearner with(c);
  auto tokens = torch::randn({2, 16, 32}), scene = torch::randn({2, 3 + 2 * 16, 32});
  torch::NoGradGuard no_grad;
  EXPECT_TRUE(torch::allclose(with(tokens, scene), official(tokens, scene), 1e-6, 1e-6));  // output layer at 0
  with->correspondence->mlp->fc2->weight.normal_(0.0, 0.1);
  auto base = with->pooled(tokens, scene);
  auto other_view0 = scene.clone();
  other_view0.narrow(1, 3, 16).normal_();
  EXPECT_FALSE(torch::allclose(with->pooled(tokens, other_view0), base));  // it reads view 0 ...
  auto other_view1 = scene.clone();
  other_view1.narrow(1, 3 + 16, 16).normal_();
  auto official_change = (official->pooled(tokens, other_view1) - official->pooled(tokens, scene)).abs().max();
  auto with_change = (with->pooled(tokens, other_view1) - base).abs().max();
  EXPECT_NEAR(with_change.item<float>(), official_change.item<float>(), 1e-5);  // ... view 1 only through the blocks
  EXPECT_NE(test::error_of([&] { with(tokens, scene.narrow(1, 0, 10)); }).find("model.keep_image_tokens"),
            std::string::npos);
}
