// Function-preserving deepening: a deeper UP-LVSM initialised from a shallower one's weights, its added blocks the
// identity, renders exactly what the shallower one renders; files that are not a shallower model are refused.
#include <gtest/gtest.h>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/model/function_preserving_deepening.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/state_dict.h"

using namespace uplvsm;

namespace {
model::Views random_views(int64_t v) {
  auto q = torch::randn({1, v, 4});
  q = q / q.norm(2, -1, true);
  auto c2w = geometry::pose_encoding_to_c2w(torch::cat({torch::randn({1, v, 3}), q}, -1));
  return {torch::rand({1, v, 3, 32, 32}), torch::tensor({30.0, 30.0, 16.0, 16.0}).expand({1, v, 4}).contiguous(), c2w};
}

ModelConfig deeper(ModelConfig m) {
  m.transformer.estimator_n_layer = 3;
  m.transformer.decoder_n_layer = 2;
  return m;
}
}  // namespace

TEST(FunctionPreservingDeepening, TheDeeperModelRendersWhatTheShallowerOneRenders) {
  torch::manual_seed(3);
  auto shallow = model::make_model(test::micro_model());
  auto deep = model::make_model(deeper(test::micro_model()));
  const auto weights = model::state_dict(*shallow);
  const auto absent = model::blocks_absent_from(*deep, weights, "shallow.safetensors");
  EXPECT_EQ(absent, (std::vector<std::string>{"transformer_decoder.1", "estimator.transformer_estimator.1",
                                              "estimator.transformer_estimator.2"}));
  model::LoadOptions load;
  for (const auto& block : absent) load.allow_missing_substrings.push_back(block + ".");
  auto report = model::load_state_dict(*deep, weights, "shallow.safetensors", load);
  EXPECT_EQ(report.missing.size(), 0u);
  model::make_blocks_identity(*deep, absent);

  shallow->eval();
  deep->eval();
  torch::NoGradGuard no_grad;
  const auto inputs = random_views(2), targets = random_views(2);
  const auto a = shallow->render(inputs, targets, model::TargetPoses::Estimator);
  const auto b = deep->render(inputs, targets, model::TargetPoses::Estimator);
  // Equal up to float summation order (a stack's last block computes only the rows its caller reads, so the blocks
  // before it run on other matrix shapes).
  EXPECT_LT((a.render - b.render).abs().max().item<double>(), 1e-6);
  EXPECT_LT((a.pose_enc - b.pose_enc).abs().max().item<double>(), 1e-6);
  // Without the identity start the added blocks (random weights) change the render: the test can fail.
  auto unchanged = model::make_model(deeper(test::micro_model()));
  model::load_state_dict(*unchanged, weights, "shallow.safetensors", load);
  unchanged->eval();
  EXPECT_GT(
      (unchanged->render(inputs, targets, model::TargetPoses::Estimator).render - a.render).abs().max().item<double>(),
      1e-4);
}

TEST(FunctionPreservingDeepening, TheAddedBlocksStillLearn) {
  auto deep = model::make_model(deeper(test::micro_model()));
  model::make_blocks_identity(*deep, {"transformer_decoder.1"});
  deep->train();
  const auto inputs = random_views(2), targets = random_views(2);
  deep->render(inputs, targets, model::TargetPoses::Estimator).render.square().mean().backward();
  const auto params = deep->named_parameters();
  // The zeroed output projections get a gradient (their inputs are not zero), so the block grows from step one.
  EXPECT_GT(params["transformer_decoder.1.attn.fc.weight"].grad().abs().max().item<double>(), 0.0);
  EXPECT_GT(params["transformer_decoder.1.mlp.mlp.2.weight"].grad().abs().max().item<double>(), 0.0);
  EXPECT_EQ(params["transformer_decoder.1.mlp.mlp.2.weight"].abs().max().item<double>(), 0.0);
}

TEST(FunctionPreservingDeepening, FilesThatAreNotAShallowerModelAreRefused) {
  auto deep = model::make_model(deeper(test::micro_model()));
  auto weights = model::state_dict(*deep);
  EXPECT_TRUE(model::blocks_absent_from(*deep, weights, "same.safetensors").empty());

  auto partial = weights;
  partial.erase("transformer_decoder.1.attn.fc.weight");
  try {
    model::blocks_absent_from(*deep, partial, "partial.safetensors");
    FAIL() << "a block only partly in the file was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("partial.safetensors: transformer block transformer_decoder.1 is only partly"),
              std::string::npos)
        << e.what();
  }

  auto gap = weights;  // estimator block 1 absent while block 2 is present: not an appended block
  for (auto it = gap.begin(); it != gap.end();)
    it = it->first.rfind("estimator.transformer_estimator.1.", 0) == 0 ? gap.erase(it) : std::next(it);
  EXPECT_NE(
      test::error_of([&] { model::blocks_absent_from(*deep, gap, "gap.safetensors"); })
          .find("gap.safetensors: transformer block estimator.transformer_estimator.1 is absent from the file but "
                "a later block"),
      std::string::npos);
  EXPECT_THROW(model::make_blocks_identity(*deep, {"transformer_decoder"}), std::runtime_error);
}
