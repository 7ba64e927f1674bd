// Tests of train/estimator_half_view: the halves the estimator is shown (one side per target, both sides drawn, keyed
// to the seed and the step) and the MSE over the other half against a direct computation.
#include "uplvsm/train/estimator_half_view.h"

#include <gtest/gtest.h>

using namespace uplvsm;
using torch::indexing::Slice;

TEST(EstimatorHalfView, EachTargetSeesOneWholeSideAndBothSidesAreDrawn) {
  TrainingConfig tc;
  const int64_t count = 64, H = 6, W = 9;  // an odd width: the left half is columns [0, 4)
  auto seen = train::draw_seen_halves(count, H, W, tc, 5);
  ASSERT_EQ(seen.sizes(), (std::vector<int64_t>{count, 1, H, W}));
  auto left = torch::zeros({1, 1, H, W});
  left.index_put_({Slice(), Slice(), Slice(), Slice(0, W / 2)}, 1.0);
  int64_t lefts = 0, rights = 0;
  for (int64_t i = 0; i < count; ++i) {
    const bool is_left = torch::equal(seen[i].unsqueeze(0), left),
               is_right = torch::equal(seen[i].unsqueeze(0), 1 - left);
    EXPECT_TRUE(is_left || is_right) << "target " << i;
    lefts += is_left;
    rights += is_right;
  }
  EXPECT_GT(lefts, 10);
  EXPECT_GT(rights, 10);
  EXPECT_TRUE(torch::equal(seen, train::draw_seen_halves(count, H, W, tc, 5)))
      << "keyed to the step: a resume draws the same";
  EXPECT_FALSE(torch::equal(seen, train::draw_seen_halves(count, H, W, tc, 6)));
  tc.seed += 1;
  EXPECT_FALSE(torch::equal(seen, train::draw_seen_halves(count, H, W, tc, 5)));
}

TEST(EstimatorHalfView, MaskedMseIsTheMseOfTheScoredPixelsAlone) {
  torch::manual_seed(3);
  auto render = torch::rand({2, 3, 3, 8, 10}), target = torch::rand({2, 3, 3, 8, 10});
  EXPECT_NEAR(train::masked_mse(render, target, torch::ones({2, 3, 1, 8, 10})).item<double>(),
              torch::mse_loss(render, target).item<double>(), 1e-7);
  auto right = torch::zeros({2, 3, 1, 8, 10});
  right.index_put_({"...", Slice(5, 10)}, 1.0);
  auto direct = torch::mse_loss(render.index({"...", Slice(5, 10)}), target.index({"...", Slice(5, 10)}));
  EXPECT_NEAR(train::masked_mse(render, target, right).item<double>(), direct.item<double>(), 1e-7);
  // The pixels not scored do not matter at all.
  auto changed = render.clone();
  changed.index_put_({"...", Slice(0, 5)}, 7.0);
  EXPECT_EQ(train::masked_mse(changed, target, right).item<double>(),
            train::masked_mse(render, target, right).item<double>());
}
