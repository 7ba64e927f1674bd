// The structural-dissimilarity training term against the evaluation's scikit-image SSIM (eval/metrics.h, itself
// checked against scikit-image): the same value, and the same gradient as autograd through that independent
// computation in float64.
#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/train/structural_dissimilarity_loss.h"

using namespace uplvsm;

TEST(StructuralDissimilarityLoss, IsOneMinusTheEvaluationsSsim) {
  torch::manual_seed(11);
  auto target = torch::rand({2, 3, 3, 20, 27});
  auto pred = (0.6 * target + 0.4 * torch::rand({2, 3, 3, 20, 27})).to(torch::kFloat32);
  const double expected = 1 - eval::ssim(pred, target).mean().item<double>();
  EXPECT_NEAR(train::structural_dissimilarity_loss(pred, target).item<double>(), expected, 2e-6);
  EXPECT_NEAR(train::structural_dissimilarity_loss(target, target).item<double>(), 0.0, 1e-6);
  // A blur of the truth loses structure, so it costs more than under the MSE's view of the same error.
  auto blurred = torch::nn::functional::avg_pool2d(
                     target.flatten(0, 1),
                     torch::nn::functional::AvgPool2dFuncOptions(3).stride(1).padding(1).count_include_pad(false))
                     .view_as(target);
  EXPECT_GT(train::structural_dissimilarity_loss(blurred, target).item<double>(), 0.3);
}

TEST(StructuralDissimilarityLoss, GradientMatchesAutogradThroughTheEvaluationsSsim) {
  torch::manual_seed(12);
  auto target = torch::rand({1, 3, 16, 13}, torch::kFloat64);
  auto start = (0.5 * target + 0.5 * torch::rand({1, 3, 16, 13}, torch::kFloat64));
  auto pred32 = start.to(torch::kFloat32).requires_grad_();
  train::structural_dissimilarity_loss(pred32, target).backward();
  auto pred64 = start.clone().requires_grad_();
  (1 - eval::ssim(pred64, target).mean()).backward();
  auto reference = pred64.grad();
  ASSERT_GT(reference.abs().max().item<double>(), 0);
  EXPECT_LT((pred32.grad().to(torch::kFloat64) - reference).abs().max().item<double>(),
            1e-4 * reference.abs().max().item<double>());
  EXPECT_FALSE(target.requires_grad());
}

TEST(StructuralDissimilarityLoss, RejectsMismatchedOrTooSmallImages) {
  EXPECT_NE(test::error_of([] {
              train::structural_dissimilarity_loss(torch::rand({1, 3, 16, 16}), torch::rand({1, 3, 16, 15}));
            }).find("one shape"),
            std::string::npos);
  EXPECT_NE(test::error_of([] {
              train::structural_dissimilarity_loss(torch::rand({1, 3, 10, 16}), torch::rand({1, 3, 10, 16}));
            }).find("smaller than the 11x11 window"),
            std::string::npos);
}
