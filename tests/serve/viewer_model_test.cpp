// The viewer's model adapter: cameras in real units through the mapper (dataset cameras, or photos placed by
// inverting the mapper), posed models refused.
#include <gtest/gtest.h>

#include "serve_test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/model/model_factory.h"

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
  EXPECT_LT(max_abs_diff(photos.key_real[0], identity), 1e-5);
  EXPECT_NEAR(photos.key_real[1].slice(0, 0, 3).norm().item<double>(), 1.0, 1e-5);

  // A real camera renders as its mapped latent pose does.
  auto real = posed.key_real.slice(0, 1, 2);
  auto through_mapper = viewer.render(posed, real, serve::PoseSpace::Real);
  EXPECT_EQ(through_mapper.sizes(), (std::vector<int64_t>{1, 3, 48, 48}));
  EXPECT_GT(posed.bytes(), posed.latents.numel() * 4 - 1);
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
