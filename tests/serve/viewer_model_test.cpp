// The viewer's model adapter: cameras in real units through the mapper (dataset cameras, or photos placed by
// inverting the mapper), posed models refused.
#include <gtest/gtest.h>

#include <cmath>

#include "serve_test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/pose_mapper.h"

namespace uplvsm::test {
namespace {

TEST(ViewerModel, RealCamerasOfDatasetViewsAndPhotos) {
  auto viewer = tiny_viewer_model(true);
  ASSERT_TRUE(viewer.has_mapper());
  data::ChunkDataset dataset(tiny_dataset("viewer_model", 1), "test");
  auto views = dataset.load_views(0, {0, 4}, {48, 8, true});
  auto posed = viewer.encode(views, true);
  ASSERT_TRUE(posed.key_real.defined());
  EXPECT_FALSE(posed.key_real_estimated);
  auto identity = torch::tensor({0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}, torch::kFloat64);
  EXPECT_LT(max_abs_diff(posed.key_real[0], identity), 1e-5);
  EXPECT_NEAR(posed.key_real[1].slice(0, 0, 3).norm().item<double>(), 1.0, 1e-5);  // one baseline

  auto photos = viewer.encode(views, false);  // no cameras: input 2 is placed through the inverse mapper
  EXPECT_TRUE(photos.key_real_estimated);
  EXPECT_TRUE(std::isfinite(photos.key_real_residual) && std::isnan(posed.key_real_residual));
  EXPECT_LT(max_abs_diff(photos.key_real[0], identity), 1e-5);
  EXPECT_NEAR(photos.key_real[1].slice(0, 0, 3).norm().item<double>(), 1.0, 1e-5);

  // A real camera renders as its mapped latent pose does.
  auto real = posed.key_real.slice(0, 1, 2);
  auto through_mapper = viewer.render(posed, real, serve::PoseSpace::Real);
  EXPECT_EQ(through_mapper.sizes(), (std::vector<int64_t>{1, 3, 48, 48}));
  EXPECT_GT(posed.bytes(), posed.latents.numel() * 4 - 1);
}

TEST(ViewerModel, APhotoPlacedThroughAnMlpMapperRendersAsTheEstimatorReadIt) {
  torch::manual_seed(7);
  Config c = tiny_config(false);
  model::UPLVSM net(c.model);
  model::PoseMapper mapper(model::PoseMapperOptions{model::PoseMapperKind::Mlp, 32});
  {
    torch::NoGradGuard no_grad;
    for (auto& p : mapper->mlp->parameters()) p.normal_(0, 0.3);  // as steep as its linear part
  }
  net->attach_pose_mapper(mapper);
  serve::ViewerModel viewer(net.ptr(), c, false);
  data::ChunkDataset dataset(tiny_dataset("viewer_model_mlp", 1), "test");
  auto views = dataset.load_views(0, {0, 4}, {48, 8, true});
  const auto key_latent = viewer.encode(views, false).key_latent;
  {
    // b moved so that a known real pose one baseline away maps exactly onto the second photo's latent pose.
    torch::NoGradGuard no_grad;
    auto q = torch::tensor({0.05, 0.1, -0.02, 0.99});
    auto x = torch::cat({torch::tensor({0.8, 0.0, 0.6}), q / q.norm()}).unsqueeze(0);
    auto s = model::scene_conditioning(key_latent.unsqueeze(0));
    auto before_normalising =
        torch::matmul(x, mapper->A.t()) + mapper->b + mapper->mlp->forward(torch::cat({x, s}, -1));
    mapper->b.add_(key_latent[1].to(torch::kFloat32) - before_normalising[0]);
  }
  auto photos = viewer.encode(views, false);
  ASSERT_TRUE(photos.key_real_estimated);
  EXPECT_LT(photos.key_real_residual, 1e-4);
  auto at_real = viewer.render(photos, photos.key_real.slice(0, 1, 2), serve::PoseSpace::Real);
  auto estimator = viewer.render(photos, photos.key_latent.slice(0, 1, 2), serve::PoseSpace::Latent);
  EXPECT_LT(max_abs_diff(at_real, estimator), 1e-5);
  // The comparison has teeth: the first photo's latent pose renders another picture (this random model's renders
  // move little with the pose: by 0.005 between the two photos' poses).
  EXPECT_GT(max_abs_diff(viewer.render(photos, photos.key_latent.slice(0, 0, 1), serve::PoseSpace::Latent), estimator),
            1e-3);
}

TEST(ViewerModel, WithoutMapperOnlyLatentPoses) {
  auto viewer = tiny_viewer_model(false);
  data::ChunkDataset dataset(tiny_dataset("viewer_model_latent", 1), "test");
  auto scene = viewer.encode(dataset.load_views(0, {0, 4}, {48, 8, true}), true);
  EXPECT_FALSE(scene.key_real.defined());
  EXPECT_THROW(viewer.render(scene, scene.key_latent, serve::PoseSpace::Real), std::invalid_argument);
  auto frames = viewer.render(scene, scene.key_latent, serve::PoseSpace::Latent);
  EXPECT_EQ(frames.sizes(), (std::vector<int64_t>{2, 3, 48, 48}));
  EXPECT_GE(frames.min().item<float>(), 0.0f);
  EXPECT_LE(frames.max().item<float>(), 1.0f);
}

TEST(ViewerModel, PosedModelsAreRefused) {
  Config c = tiny_config(false);
  c.model.variant = Variant::PTLVSM;
  c.model.transformer.n_layer = 2;
  const auto dir = temp_dir("viewer_posed");
  const auto path = (dir / "ptlvsm.safetensors").string();
  auto net = model::make_model(c.model);
  io::write_checkpoint(path, c, {{"step", 0}}, io::state_dict(*net), {});
  auto message = error_of([&] { serve::ViewerModel::load(path, "", torch::kCPU, false); });
  EXPECT_NE(message.find("PT-LVSM"), std::string::npos) << message;
  remove_tree(dir);
}

}  // namespace
}  // namespace uplvsm::test
