// Tests of eval/baselines on hand-made tensors: nearest-frame choice with ties, batch indexing, and the mean
// colour being the best constant image under MSE.
#include "uplvsm/eval/baselines.h"

#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/eval/metrics.h"

namespace uplvsm::eval {
namespace {

TEST(Baselines, NearestInputTiesGoToTheFirst) {
  EXPECT_EQ(nearest_input({0, 10}, 3), 0);
  EXPECT_EQ(nearest_input({0, 10}, 7), 1);
  EXPECT_EQ(nearest_input({0, 10}, 5), 0);  // tie
  EXPECT_EQ(nearest_input({10, 0}, 5), 0);  // tie: the first listed, whatever its frame
  EXPECT_EQ(nearest_input({4, 8}, 20), 1);
  EXPECT_THROW(nearest_input({}, 1), std::runtime_error);
}

TEST(Baselines, CopyNearestInputPicksPerBatchElement) {
  // Input view v of batch element b is the constant 10 b + v.
  auto images = torch::zeros({2, 2, 3, 4, 5});
  for (int b = 0; b < 2; ++b)
    for (int v = 0; v < 2; ++v) images[b][v].fill_(10.0 * b + v);
  auto out = copy_nearest_input(images, {{0, 10}, {5, 20}}, {{1, 5, 9}, {12, 13, 0}});
  ASSERT_EQ(out.sizes(), (std::vector<int64_t>{2, 3, 3, 4, 5}));
  const double expected[2][3] = {{0, 0, 1}, {10, 11, 10}};  // 13 is 8 from 5 and 7 from 20
  for (int b = 0; b < 2; ++b)
    for (int t = 0; t < 3; ++t) EXPECT_TRUE(torch::all(out[b][t] == expected[b][t]).item<bool>()) << b << " " << t;
}

// c2w whose camera z axis (viewing direction) points along `yaw` radians about the y axis.
torch::Tensor looking_along(double yaw) {
  auto m = torch::eye(4, torch::kFloat64);
  m[0][0] = std::cos(yaw), m[0][2] = std::sin(yaw), m[2][0] = -std::sin(yaw), m[2][2] = std::cos(yaw);
  m[0][3] = 5.0 * std::sin(yaw);  // positions alone would say otherwise for some pairs: only directions count
  return m;
}

TEST(Baselines, CopyNearestDirectionPicksTheClosestViewingDirection) {
  auto images = torch::zeros({2, 2, 3, 4, 5});
  for (int b = 0; b < 2; ++b)
    for (int v = 0; v < 2; ++v) images[b][v].fill_(10.0 * b + v);
  auto in = torch::stack(
      {torch::stack({looking_along(0), looking_along(1.5)}), torch::stack({looking_along(3.0), looking_along(-1.0)})});
  auto tg = torch::stack({torch::stack({looking_along(0.2), looking_along(1.0), looking_along(0.7)}),
                          torch::stack({looking_along(2.5), looking_along(-0.5), looking_along(1.2)})});
  auto out = copy_nearest_direction(images, in, tg);
  ASSERT_EQ(out.sizes(), (std::vector<int64_t>{2, 3, 3, 4, 5}));
  // 1.2 is 1.8 rad from 3.0 and 2.2 rad from -1.0.
  const double expected[2][3] = {{0, 1, 0}, {10, 11, 10}};
  for (int b = 0; b < 2; ++b)
    for (int t = 0; t < 3; ++t) EXPECT_TRUE(torch::all(out[b][t] == expected[b][t]).item<bool>()) << b << " " << t;
  EXPECT_THROW(copy_nearest_direction(images, in.narrow(1, 0, 1), tg), c10::Error);
}

TEST(Baselines, CopyNearestInputRejectsInconsistentFrames) {
  auto images = torch::zeros({1, 2, 3, 4, 4});
  EXPECT_THROW(copy_nearest_input(images, {{0}}, {{1}}), std::runtime_error);                  // 1 frame, 2 views
  EXPECT_THROW(copy_nearest_input(images, {{0, 1}, {0, 1}}, {{1}, {2}}), std::runtime_error);  // batch 2 vs 1
  EXPECT_THROW(copy_nearest_input(images[0], {{0, 1}}, {{1}}), std::runtime_error);            // not 5-D
}

TEST(Baselines, MeanColourIsTheBestConstant) {
  torch::manual_seed(0);
  auto target = torch::rand({2, 3, 3, 16, 16});
  auto pred = mean_colour(target);
  ASSERT_EQ(pred.sizes(), target.sizes());
  auto expected = target.mean({-2, -1});
  EXPECT_LE(test::max_abs_diff(pred.amax({-2, -1}), expected), 1e-7);
  EXPECT_LE(test::max_abs_diff(pred.amin({-2, -1}), expected), 1e-7);
  // Any other constant has a lower PSNR.
  auto best = psnr(pred, target);
  for (double delta : {-0.02, 0.01, 0.05})
    EXPECT_TRUE(torch::all(psnr(pred + delta, target) < best).item<bool>()) << delta;
  // A constant target is predicted perfectly.
  auto flat = torch::full({1, 3, 12, 12}, 0.25);
  EXPECT_NEAR(psnr(mean_colour(flat), flat).item<double>(), 100.0, 1e-9);
}

}  // namespace
}  // namespace uplvsm::eval
