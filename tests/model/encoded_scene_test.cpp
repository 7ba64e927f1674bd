// The encoded scene the renderer, the viewer and the Python module render from: encoded once, it holds the model's
// scene latents and the estimator's latent poses of the inputs, and decodes latent poses (in chunks or at once) and
// real cameras through the pose mapper as the model itself would.
#include "uplvsm/model/encoded_scene.h"

#include <gtest/gtest.h>

#include "train/train_test_util.h"
#include "uplvsm/model/model_factory.h"

using namespace uplvsm;

namespace {

model::UPLVSM micro_net() {
  torch::manual_seed(11);
  auto net = model::require_uplvsm(model::make_model(test::micro_model()), "test");
  net->eval();
  return net;
}

}  // namespace

TEST(EncodedScene, HoldsTheModelsLatentsAndInputPosesAndDecodesThem) {
  auto net = micro_net();
  torch::NoGradGuard no_grad;
  torch::manual_seed(2);
  const auto images = torch::rand({2, 3, 32, 32});
  const auto k = torch::tensor({{30.0f, 30.0f, 16.0f, 16.0f}, {28.0f, 28.0f, 16.0f, 16.0f}});
  const auto scene = model::encode_scene(*net, images, k);
  const auto latents = net->encode_scene(images.unsqueeze(0), k.unsqueeze(0));
  EXPECT_TRUE(torch::equal(scene.latents, latents));
  EXPECT_TRUE(torch::equal(scene.input_poses, net->estimate_poses(images.unsqueeze(0), latents)[0]));
  EXPECT_EQ(scene.height, 32);
  EXPECT_FALSE(model::encode_scene(*net, images, k, false).input_poses.defined());

  const auto poses = torch::cat({scene.input_poses, scene.input_poses.flip(0), scene.input_poses.mean(0, true)});
  const auto intrinsics = torch::cat({k, k, k.slice(0, 0, 1)});
  const auto direct = net->render_views(latents, poses.unsqueeze(0), intrinsics.unsqueeze(0), 32, 32)[0];
  const auto at_once = model::render_latent_poses(*net, scene, poses, intrinsics);
  ASSERT_EQ(at_once.sizes(), (std::vector<int64_t>{5, 3, 32, 32}));
  EXPECT_LT(test::max_abs_diff(at_once, direct), 1e-5);
  EXPECT_LT(test::max_abs_diff(model::render_latent_poses(*net, scene, poses, intrinsics, 2), at_once), 1e-5);
}

TEST(EncodedScene, RealCamerasGoThroughTheMapperWithTheInputsPoses) {
  auto net = micro_net();
  torch::NoGradGuard no_grad;
  const auto images = torch::rand({2, 3, 32, 32});
  const auto k = torch::tensor({{30.0f, 30.0f, 16.0f, 16.0f}, {30.0f, 30.0f, 16.0f, 16.0f}});
  const auto scene = model::encode_scene(*net, images, k);
  const auto real = torch::tensor({{0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}, {0.5, 0.0, 0.1, 0.0, 0.1, 0.0, 0.995}});
  EXPECT_ANY_THROW(model::latent_poses_of_cameras(*net, scene, real));  // no mapper yet
  torch::manual_seed(4);
  model::PoseMapper mapper(model::PoseMapperOptions{model::PoseMapperKind::Mlp, 8});
  for (auto& p : mapper->parameters()) p.normal_(0, 0.5);  // its MLP starts at zero: made to read the scene
  net->attach_pose_mapper(mapper);
  const auto conditioning = model::scene_conditioning(scene.input_poses.unsqueeze(0));
  EXPECT_TRUE(torch::equal(model::mapper_conditioning(scene), conditioning));
  const auto expected = net->pose_mapper(real.to(torch::kFloat32).unsqueeze(0), conditioning)[0];
  EXPECT_TRUE(torch::equal(model::latent_poses_of_cameras(*net, scene, real), expected));
  EXPECT_ANY_THROW(model::mapper_conditioning(model::encode_scene(*net, images, k, false)));
}
