// The wobble measure on pictures whose motion is known exactly: textures of a few sinusoids slid by sub-pixel
// amounts. It must read steady motion as 0 at any speed and texture (the earlier figure grew with both), grow in
// proportion to a known wobble, and, given the truth, not count the truth's own change of motion.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "test_util.h"
#include "uplvsm/eval/picture_motion.h"

using namespace uplvsm;

namespace {

struct Texture {
  std::vector<double> wavelength, angle, phase;
};
const Texture kCoarse{{23.0, 29.0, 19.0}, {0.3, 1.9, 4.0}, {0.0, 1.0, 2.5}};
const Texture kFine{{8.5, 10.0, 12.0}, {0.7, 2.3, 5.1}, {0.4, 2.0, 1.1}};

// Frames [T, 3, 40, 56] of `texture` moved to positions[t] pixels along a fixed direction.
torch::Tensor slide(const Texture& texture, const std::vector<double>& positions) {
  auto x = torch::arange(56, torch::kFloat64).view({1, 1, 56});
  auto y = torch::arange(40, torch::kFloat64).view({1, 40, 1});
  auto p = torch::tensor(positions, torch::kFloat64).view({-1, 1, 1});
  auto xs = x - p * std::cos(0.4), ys = y - p * std::sin(0.4);
  auto f = torch::full({static_cast<int64_t>(positions.size()), 40, 56}, 0.5, torch::kFloat64);
  for (size_t k = 0; k < texture.wavelength.size(); ++k)
    f = f + 0.12 * torch::sin((xs * std::cos(texture.angle[k]) + ys * std::sin(texture.angle[k])) *
                                  (2 * M_PI / texture.wavelength[k]) +
                              texture.phase[k]);
  return f.unsqueeze(1).expand({-1, 3, 40, 56}).contiguous();
}

// Positions of a steady slide at `speed` pixels per frame, each frame pushed ±amplitude about it in turn, plus
// `acceleration` (pixels per frame²) of smooth speeding up.
std::vector<double> path(double speed, double amplitude = 0, double acceleration = 0, int frames = 9) {
  std::vector<double> p;
  for (int t = 0; t < frames; ++t) p.push_back(speed * t + amplitude * (t % 2 ? 1 : -1) + acceleration * t * t / 2);
  return p;
}

}  // namespace

TEST(PictureMotion, SteadySlidesScoreTheSameAtAnySpeedAndTexture) {
  for (const auto* texture : {&kCoarse, &kFine})
    for (double speed : {0.25, 0.5, 1.0, 2.0}) {
      auto frames = slide(*texture, path(speed));
      EXPECT_LT(eval::temporal_wobble(frames), 0.03) << "speed " << speed;  // a ±0.05 px wobble: 0.2
      EXPECT_NEAR(eval::picture_speed(frames), speed, 0.05 * speed) << "speed " << speed;
    }
  EXPECT_EQ(eval::temporal_wobble(torch::full({5, 3, 40, 56}, 0.3)), 0.0);  // nothing to follow
}

TEST(PictureMotion, AWobbleScoresInProportionToItsAmplitude) {
  // ±A about the path every other frame: the motion swings by 4A from one frame to the next.
  for (const auto* texture : {&kCoarse, &kFine})
    for (double amplitude : {0.05, 0.1, 0.2}) {
      const double w = eval::temporal_wobble(slide(*texture, path(0.5, amplitude)));
      EXPECT_NEAR(w, 4 * amplitude, 0.15 * 4 * amplitude) << "amplitude " << amplitude;
    }
  EXPECT_NE(test::error_of([] { eval::temporal_wobble(slide(kCoarse, path(0.5, 0, 0, 2))); }).find("T >= 3"),
            std::string::npos);
}

TEST(PictureMotion, TheTruthsOwnChangeOfMotionIsNotWobble) {
  // The truth speeds up (0.1 px/frame²): alone, that reads as a change of motion.
  auto truth = slide(kCoarse, path(0.3, 0, 0.1));
  EXPECT_NEAR(eval::temporal_wobble(truth), 0.1, 0.015);
  // A render that follows it 0.7 px behind and blurred does not wobble; one that also jumps ±0.1 px does, by 0.4.
  namespace F = torch::nn::functional;
  auto blur = [](const torch::Tensor& x) {
    return F::avg_pool2d(x, F::AvgPool2dFuncOptions(3).stride(1).padding(1).count_include_pad(false));
  };
  auto behind = path(0.3, 0, 0.1);
  for (auto& p : behind) p -= 0.7;
  auto lagging = blur(slide(kCoarse, behind));
  EXPECT_LT(eval::temporal_wobble(lagging, truth), 0.02);
  auto wobbling = blur(slide(kCoarse, path(0.3, 0.1, 0.1)));
  EXPECT_NEAR(eval::temporal_wobble(wobbling, truth), 0.4, 0.06);
  EXPECT_NE(test::error_of([&] { eval::temporal_wobble(wobbling, truth.narrow(0, 0, 4)); }).find("shape"),
            std::string::npos);
}
