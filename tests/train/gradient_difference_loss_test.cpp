// The gradient difference loss against its definition written as plain loops over pixel pairs (float64), and what
// it is for: a blur of the truth costs more than the truth, and a descent step on it sharpens the blur.
#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/train/gradient_difference_loss.h"

using namespace uplvsm;

namespace {

double loop_gradient_difference(const torch::Tensor& pred, const torch::Tensor& target) {
  auto p = pred.to(torch::kFloat64).contiguous(), t = target.to(torch::kFloat64).contiguous();
  auto a = p.accessor<double, 4>(), b = t.accessor<double, 4>();
  double sum = 0;
  int64_t count = 0;
  for (int64_t n = 0; n < p.size(0); ++n)
    for (int64_t c = 0; c < p.size(1); ++c)
      for (int64_t y = 0; y < p.size(2); ++y)
        for (int64_t x = 0; x < p.size(3); ++x) {
          if (x + 1 < p.size(3)) {
            sum += std::abs(std::abs(a[n][c][y][x + 1] - a[n][c][y][x]) - std::abs(b[n][c][y][x + 1] - b[n][c][y][x]));
            ++count;
          }
          if (y + 1 < p.size(2)) {
            sum += std::abs(std::abs(a[n][c][y + 1][x] - a[n][c][y][x]) - std::abs(b[n][c][y + 1][x] - b[n][c][y][x]));
            ++count;
          }
        }
  return sum / static_cast<double>(count);
}

}  // namespace

TEST(GradientDifferenceLoss, MatchesTheDefinitionOverPixelPairs) {
  torch::manual_seed(21);
  auto target = torch::rand({2, 3, 9, 7});
  auto pred = torch::rand({2, 3, 9, 7});
  EXPECT_NEAR(train::gradient_difference_loss(pred, target).item<double>(), loop_gradient_difference(pred, target),
              1e-6);
  EXPECT_NEAR(train::gradient_difference_loss(pred.view({1, 2, 3, 9, 7}), target.view({1, 2, 3, 9, 7})).item<double>(),
              loop_gradient_difference(pred, target), 1e-6);  // any leading shape
  EXPECT_EQ(train::gradient_difference_loss(target, target).item<double>(), 0.0);
}

TEST(GradientDifferenceLoss, PenalisesABlurAndItsDescentSharpens) {
  torch::manual_seed(22);
  auto target = (torch::rand({1, 3, 24, 24}) > 0.5).to(torch::kFloat32);  // hard edges everywhere
  namespace F = torch::nn::functional;
  auto blurred = F::avg_pool2d(target, F::AvgPool2dFuncOptions(3).stride(1).padding(1).count_include_pad(false));
  auto pred = blurred.clone().requires_grad_();
  auto loss = train::gradient_difference_loss(pred, target);
  EXPECT_GT(loss.item<double>(), 0.1);
  loss.backward();
  auto stepped = (blurred - 0.5 * pred.grad() * static_cast<double>(pred.numel())).clamp(0, 1);
  EXPECT_GT(eval::gradient_energy(stepped).item<double>(), eval::gradient_energy(blurred).item<double>());
  EXPECT_LT(train::gradient_difference_loss(stepped, target).item<double>(), loss.item<double>());
}

TEST(GradientDifferenceLoss, RejectsMismatchedOrFlatImages) {
  EXPECT_NE(test::error_of([] {
              train::gradient_difference_loss(torch::rand({1, 3, 4, 4}), torch::rand({1, 3, 4, 5}));
            }).find("one shape"),
            std::string::npos);
  EXPECT_NE(test::error_of([] {
              train::gradient_difference_loss(torch::rand({1, 3, 1, 4}), torch::rand({1, 3, 1, 4}));
            }).find("no pixel pairs"),
            std::string::npos);
}
