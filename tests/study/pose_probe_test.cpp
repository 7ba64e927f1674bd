#include <gtest/gtest.h>

#include <fstream>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/study/pose_probe.h"

using namespace uplvsm;

namespace {
torch::Tensor random_poses(int64_t n) {
  auto q = torch::randn({n, 4}, torch::kFloat64);
  q = q / q.norm(2, 1, true);
  q = q * torch::where(q.select(1, 3) < 0, -1.0, 1.0).unsqueeze(1);
  return torch::cat({torch::randn({n, 3}, torch::kFloat64), q}, 1);
}
study::PosePairs pairs_from(const torch::Tensor& latent, const torch::Tensor& real) {
  study::PosePairs p;
  p.latent = latent;
  p.real = real;
  for (int64_t i = 0; i < latent.size(0); ++i) p.scenes.push_back("s"), p.frames.push_back(i + 1);
  return p;
}
}  // namespace

TEST(PoseAccuracy, ThresholdsOnKnownErrors) {
  torch::manual_seed(0);
  auto real = random_poses(10);
  auto shifted = real.clone();
  shifted.select(1, 0).add_(0.15);  // translation error 0.15
  auto a = study::pose_accuracy(shifted, real);
  EXPECT_EQ(a.translation_accuracy, (std::vector<double>{0.0, 1.0, 1.0}));
  EXPECT_EQ(a.rotation_accuracy, (std::vector<double>{1.0, 1.0, 1.0}));
  EXPECT_NEAR(a.median_translation_error, 0.15, 1e-9);
  // A 15-degree turn about z: rotation error 15 degrees whatever the quaternion's sign.
  auto turn = geometry::pose_encoding_to_c2w(torch::tensor(
      {{0.0, 0.0, 0.0, 0.0, 0.0, std::sin(M_PI * 15 / 360), std::cos(M_PI * 15 / 360)}}, torch::kFloat64));
  auto rotated = geometry::c2w_to_pose_encoding(torch::matmul(geometry::pose_encoding_to_c2w(real), turn));
  rotated.slice(1, 3, 7).neg_();
  auto b = study::pose_accuracy(torch::cat({real.slice(1, 0, 3), rotated.slice(1, 3, 7)}, 1), real);
  EXPECT_EQ(b.rotation_accuracy, (std::vector<double>{0.0, 1.0, 1.0}));
  EXPECT_NEAR(b.median_rotation_error_deg, 15.0, 1e-6);
  auto j = study::to_json(b);
  EXPECT_DOUBLE_EQ(j.at("rot@20").get<double>(), 1.0);
}

TEST(PoseProbe, LinearProbeInvertsALinearLatentSpaceAndMlpFitsATwistedOne) {
  torch::manual_seed(1);
  auto real = random_poses(600);
  real.slice(1, 0, 3).mul_(0.5);
  auto A = torch::randn({7, 7}, torch::kFloat64) + 3 * torch::eye(7, torch::kFloat64);
  auto linear_latent = torch::matmul(real, A.t()) + 0.3;
  auto train = pairs_from(linear_latent.slice(0, 0, 500), real.slice(0, 0, 500));
  auto test_latent = linear_latent.slice(0, 500), test_real = real.slice(0, 500);
  auto lin = study::pose_accuracy(study::fit_and_apply_linear_probe(train, test_latent), test_real);
  EXPECT_GT(lin.translation_accuracy[0], 0.99);
  EXPECT_GT(lin.rotation_accuracy[0], 0.99);
  // A smooth non-linear ("twisted") latent space: the MLP probe recovers translations that a linear map cannot.
  auto t = 2 * real.slice(1, 0, 3);
  auto twisted = torch::cat({t.pow(3) + 0.2 * t, real.slice(1, 3, 7)}, 1);
  auto train2 = pairs_from(twisted.slice(0, 0, 500), real.slice(0, 0, 500));
  study::ProbeOptions po;
  po.iterations = 1500;
  auto mlp = study::pose_accuracy(study::fit_and_apply_mlp_probe(train2, twisted.slice(0, 500), po), test_real);
  auto lin2 = study::pose_accuracy(study::fit_and_apply_linear_probe(train2, twisted.slice(0, 500)), test_real);
  EXPECT_LT(mlp.median_translation_error, 0.5 * lin2.median_translation_error)
      << "mlp " << mlp.median_translation_error << " linear " << lin2.median_translation_error;
  EXPECT_GT(mlp.translation_accuracy[2], 0.8);
}

TEST(PoseProbe, MeanPoseBaselinePredictsTheTrainingMeanForEveryView) {
  auto real =
      torch::tensor({{0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}, {0.0, 0.0, 3.0, 0.0, 0.0, 0.0, -1.0}}, torch::kFloat64);
  auto train = pairs_from(torch::zeros({2, 7}, torch::kFloat64), real);
  auto mean = study::mean_pose_baseline(train, 3);
  ASSERT_EQ(mean.sizes(), (std::vector<int64_t>{3, 7}));
  // -q and q are one rotation: the mean of the two identities is the identity, not a zero quaternion.
  for (int64_t i = 0; i < 3; ++i)
    EXPECT_LE(test::max_abs_diff(mean[i], torch::tensor({0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 1.0}, torch::kFloat64)), 1e-12);
}

TEST(PosePairs, OneRowPerFrameWithTheFirstContextViewAsIdentity) {
  auto config = test::micro_config();
  torch::manual_seed(2);
  model::UPLVSM net(config.model);
  data::ChunkDataset dataset(test::micro_dataset(), "test");
  data::PreprocessOptions prep{32, 8, true};
  study::PosePairOptions opt;
  opt.gap = 5;
  opt.chunk = 4;
  auto pairs = study::collect_pose_pairs(net, dataset, prep, opt);
  const int64_t n = dataset.size() * 6;  // frames 0..5 per scene
  ASSERT_EQ(pairs.latent.sizes(), (std::vector<int64_t>{n, 7}));
  ASSERT_EQ(pairs.real.sizes(), (std::vector<int64_t>{n, 7}));
  ASSERT_EQ(pairs.frames.size(), static_cast<size_t>(n));
  // Latent and real poses share one convention: the first context view is the identity, the second one lies one
  // context baseline away.
  const auto identity = torch::tensor({0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}, torch::kFloat64);
  for (int64_t i = 0; i < n; ++i) {
    if (pairs.frames[i] == 0) {
      EXPECT_LE(test::max_abs_diff(pairs.real[i], identity), 1e-6);
      EXPECT_LE(test::max_abs_diff(pairs.latent[i], identity), 1e-5);
    }
    if (pairs.frames[i] == opt.gap) {
      EXPECT_NEAR(pairs.real[i].slice(0, 0, 3).norm().item<double>(), 1.0, 1e-5);
      EXPECT_NEAR(pairs.latent[i].slice(0, 0, 3).norm().item<double>(), 1.0, 1e-4);
    }
  }
  auto kept = study::without_canonical_views(pairs);
  EXPECT_EQ(kept.frames.size(), static_cast<size_t>(dataset.size() * 5));
  auto csv = (test::temp_dir("pose_pairs") / "pairs.csv").string();
  study::write_pose_pairs_csv(csv, pairs);
  std::ifstream in(csv);
  std::string header, line;
  std::getline(in, header);
  EXPECT_EQ(header.substr(0, 19), "scene,frame,latent_");
  int64_t rows = 0;
  while (std::getline(in, line)) ++rows;
  EXPECT_EQ(rows, n);
  // A posed model has no latent poses: it cannot become the UP-LVSM that collect_pose_pairs takes.
  auto posed = model::make_model([&] {
    auto m = config.model;
    m.variant = Variant::PTLVSM;
    return m;
  }());
  EXPECT_THROW(model::require_uplvsm(posed, "pose pairs"), c10::Error);
}
