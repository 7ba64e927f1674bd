// Camera control end to end at micro scale: after a short training, a trajectory that sits at the first input view
// reproduces that view better than the mean-colour baseline - through the estimator's latent pose (latent
// interpolation, first frame) and, after the mapper stage, through the mapper from the identity camera. Scored on
// the training scenes: this checks the camera path's mechanics, and six micro scenes say nothing of generalisation.
#include <gtest/gtest.h>

#include "train/train_test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/render/renderer.h"
#include "uplvsm/train/trainer.h"

using namespace uplvsm;

TEST(IdentityTrajectory, ReproducesTheFirstInputBetterThanItsMeanColour) {
  // The `tiny` demo model's dimensions (configs/tiny.json) on the micro dataset, with a short budget.
  auto config = test::micro_config();
  auto& t = config.model.transformer;
  config.model.image_size = 48;
  t.d = config.model.dinov2.embed_dim = 96;
  t.d_head = 32;
  config.model.dinov2.num_heads = 3;
  config.model.dinov2.pos_grid = 6;
  t.encoder_n_layer = t.decoder_n_layer = 2;
  t.n_latent_vectors = 32;
  config.training.batch_size = 4;
  config.training.lr = 1e-3;
  config.training.warmup = 50;
  config.training.train_steps = 800;
  auto base = test::temp_dir("identity_base").string();
  train::TrainOptions opt;
  opt.data_root = test::micro_dataset();
  opt.run_dir = base;
  opt.progress = false;
  train::train(config, opt);

  config.model.pose_mapper = true;
  config.training.target_poses = TargetPoses::Mapper;
  config.training.train_steps = 100;
  config.training.lr = 5e-4;
  config.training.warmup = 0;
  opt.run_dir = test::temp_dir("identity_mapper").string();
  opt.init_weights = io::resolve_checkpoint(base);
  train::train(config, opt);

  data::ChunkDataset dataset(test::micro_dataset(), "train");
  data::PreprocessOptions prep{48, 8, true};
  auto plain = model::require_uplvsm(model::load_model(base, torch::kCPU), "latent interpolation");
  auto mapped = model::load_model(opt.run_dir, torch::kCPU);
  double psnr_latent = 0, psnr_mapper = 0, psnr_mean = 0;
  for (int64_t i = 0; i < dataset.size(); ++i) {
    auto views = dataset.load_views(i, {0, 6}, prep);
    auto first = views.images[0];
    auto latent = render::render_interpolation(plain, views.images, views.fxfycxcy, 2).frames[0];
    auto identity = torch::tensor({{0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}});
    auto via_mapper = render::render_camera_path(mapped, {views.images, views.fxfycxcy, {}, {}}, identity,
                                                 views.fxfycxcy.slice(0, 0, 1))[0];
    auto mean_colour = first.mean({1, 2}, true).expand_as(first);
    psnr_latent += eval::psnr(latent.unsqueeze(0), first.unsqueeze(0)).item<double>() / dataset.size();
    psnr_mapper += eval::psnr(via_mapper.unsqueeze(0), first.unsqueeze(0)).item<double>() / dataset.size();
    psnr_mean += eval::psnr(mean_colour.unsqueeze(0), first.unsqueeze(0)).item<double>() / dataset.size();
  }
  std::cout << "identity trajectory PSNR: latent " << psnr_latent << ", mapper " << psnr_mapper << ", mean colour "
            << psnr_mean << "\n";
  EXPECT_GT(psnr_latent, psnr_mean);
  EXPECT_GT(psnr_mapper, psnr_mean);
}
