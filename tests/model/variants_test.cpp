// The model family: UP-LVSM and the posed baselines (ptlvsm, lvsm), built by the factory behind one interface, and
// UP-LVSM's target-pose sources.
#include <gtest/gtest.h>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/core/autocast.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/geometry/plucker.h"
#include "uplvsm/io/state_dict.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/posed_lvsm.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/train/flops.h"

using namespace uplvsm;
using torch::indexing::Slice;

namespace {
ModelConfig small_config(const std::string& variant) { return test::micro_model(variant); }

struct Scene {
  model::Views inputs, targets;
};

Scene random_scene(int64_t b, int64_t vi, int64_t vt) {
  auto cameras = [](int64_t b, int64_t v) {
    auto q = torch::randn({b, v, 4});
    q = q / q.norm(2, -1, true);
    return geometry::pose_encoding_to_c2w(torch::cat({torch::randn({b, v, 3}), q}, -1));
  };
  auto k = [](int64_t b, int64_t v) { return torch::tensor({30.0, 30.0, 16.0, 16.0}).expand({b, v, 4}).contiguous(); };
  return {{torch::rand({b, vi, 3, 32, 32}), k(b, vi), cameras(b, vi)},
          {torch::rand({b, vt, 3, 32, 32}), k(b, vt), cameras(b, vt)}};
}

model::Views transformed(model::Views v, const torch::Tensor& world, double scale) {
  v.c2w = torch::matmul(world, v.c2w).clone();
  v.c2w.index({"...", Slice(0, 3), 3}).mul_(scale);
  return v;
}
}  // namespace

TEST(Variants, TheFactoryBuildsOneClassPerModel) {
  auto up = model::make_model(small_config("uplvsm"));
  ASSERT_NE(model::as_uplvsm(*up), nullptr);
  EXPECT_EQ(up->name(), "UP-LVSM");
  EXPECT_EQ(up->default_target_poses(), model::TargetPoses::Estimator);
  EXPECT_FALSE(up->has_camera_control());  // no pose mapper
  for (const auto& [variant, posed, name] : {std::tuple{"ptlvsm", model::PosedInputs::First, "PT-LVSM"},
                                             std::tuple{"lvsm", model::PosedInputs::All, "LVSM"}}) {
    auto net = model::make_model(small_config(variant));
    EXPECT_EQ(model::as_uplvsm(*net), nullptr) << variant;
    auto* p = dynamic_cast<model::PosedLVSMImpl*>(net.get());
    ASSERT_NE(p, nullptr) << variant;
    EXPECT_EQ(p->posed_inputs, posed);
    EXPECT_EQ(net->name(), name);
    EXPECT_EQ(net->default_target_poses(), model::TargetPoses::Dataset);
    EXPECT_EQ(model::resolve_target_poses(TargetPoses::Auto, *net), model::TargetPoses::Dataset);
    EXPECT_TRUE(net->has_camera_control());
    EXPECT_NE(test::error_of([&] { model::require_uplvsm(net, "pose pairs"); }).find("pose pairs: only UP-LVSM"),
              std::string::npos);
  }
  // One enum from the config to the render: Auto is each model's own source.
  torch::manual_seed(3);
  torch::NoGradGuard no_grad;
  up->eval();
  auto s = random_scene(1, 2, 2);
  EXPECT_TRUE(torch::equal(up->render(s.inputs, s.targets, TargetPoses::Auto).render,
                           up->render(s.inputs, s.targets, TargetPoses::Estimator).render));
  auto posed = model::make_model(small_config("lvsm"));
  posed->eval();
  EXPECT_TRUE(torch::equal(posed->render(s.inputs, s.targets, TargetPoses::Auto).render,
                           posed->render(s.inputs, s.targets, TargetPoses::Dataset).render));
  EXPECT_NE(test::error_of([&] { posed->render(s.inputs, s.targets, TargetPoses::Estimator); }).find("'estimator'"),
            std::string::npos);
  auto mapped = small_config("ptlvsm");
  mapped.pose_mapper = true;
  EXPECT_NE(test::error_of([&] { model::make_model(mapped); }).find("model.pose_mapper"), std::string::npos);
  EXPECT_NE(test::error_of([&] { model::make_model(small_config("nerf")); }).find("'nerf'"), std::string::npos);
}

TEST(Variants, PosedVariantsHaveTheOfficialPosedTargetLvsmKeys) {
  auto net = model::make_model(small_config("ptlvsm"));
  auto sd = io::state_dict(*net);
  EXPECT_TRUE(sd.count("transformer_blocks.1.attn.q_norm.weight"));
  EXPECT_TRUE(sd.count("transformer_input_layernorm.weight"));
  EXPECT_TRUE(sd.count("canonical_pose_tokenizer.1.weight"));
  EXPECT_TRUE(sd.count("image_token_decoder.1.weight"));
  for (const auto& [key, value] : sd) {
    EXPECT_EQ(key.find("estimator."), std::string::npos) << key;
    EXPECT_EQ(key.find("transformer_encoder."), std::string::npos) << key;
    EXPECT_NE(key, "n_light_field_latent");
  }
  // The loader recognises the layout and infers the variant and depth.
  auto inferred = model::infer_model_config(sd, ModelConfig{});
  EXPECT_EQ(inferred.variant, Variant::PTLVSM);
  EXPECT_EQ(inferred.transformer.n_layer, 2);
  EXPECT_EQ(inferred.transformer.d, 32);
}

TEST(Variants, PosedVariantsRenderEveryTargetAndIgnoreTheWorldFrameAndScale) {
  for (const std::string variant : {"ptlvsm", "lvsm"}) {
    torch::manual_seed(3);
    auto net = model::make_model(small_config(variant));
    net->eval();
    auto s = random_scene(2, 2, 3);
    model::ForwardTrace trace;
    auto out = net->render(s.inputs, s.targets, model::TargetPoses::Dataset, &trace);
    ASSERT_EQ(out.render.sizes(), (std::vector<int64_t>{2, 3, 3, 32, 32})) << variant;
    EXPECT_FALSE(out.pose_enc.defined());
    // PT-LVSM poses input view 0 only; LVSM every input view.
    EXPECT_EQ(trace.canonical_plucker.size(1), variant == "lvsm" ? 2 : 1) << variant;
    // The official scene normalisation removes the world frame and the scene scale.
    auto world = geometry::pose_encoding_to_c2w(torch::tensor({{0.3, -2.0, 1.0, 0.2, -0.4, 0.1, 0.9}}));
    auto moved =
        net->render(transformed(s.inputs, world, 2.5), transformed(s.targets, world, 2.5), model::TargetPoses::Dataset);
    EXPECT_LT(test::max_abs_diff(out.render, moved.render), 1e-4) << variant;
    // Posed variants have no estimator.
    EXPECT_THROW(net->render(s.inputs, s.targets, model::TargetPoses::Estimator), c10::Error);
  }
}

// Cameras the training loader already put in the scene frame of all the sample's views (Views::camera_frame) are
// taken as they are: normalising again over only these inputs and targets would change the frame (and, with pose
// noise, normalise the noise away), so a world transform now reaches the render; unflagged views stay invariant.
TEST(Variants, PosedModelsTakeCamerasAlreadyInTheSceneFrameAsTheyAre) {
  torch::manual_seed(5);
  auto net = model::make_model(small_config("lvsm"));
  net->eval();
  auto s = random_scene(1, 2, 2);
  auto world = geometry::pose_encoding_to_c2w(torch::tensor({{0.3, -2.0, 1.0, 0.2, -0.4, 0.1, 0.9}}));
  auto flagged = [](model::Views v) {
    v.camera_frame = model::CameraFrame::Scene;
    return v;
  };
  auto out = net->render(flagged(s.inputs), flagged(s.targets), model::TargetPoses::Dataset);
  auto moved = net->render(flagged(transformed(s.inputs, world, 2.5)), flagged(transformed(s.targets, world, 2.5)),
                           model::TargetPoses::Dataset);
  EXPECT_GT(test::max_abs_diff(out.render, moved.render), 1e-3);
  // Given cameras that are in the frame of these very views, both paths agree.
  auto all = torch::cat({s.inputs.c2w, s.targets.c2w}, 1)[0];
  auto normalised = geometry::official_scene_normalize(all).unsqueeze(0);
  auto in = s.inputs, tg = s.targets;
  in.c2w = normalised.narrow(1, 0, 2);
  tg.c2w = normalised.narrow(1, 2, 2);
  auto given = net->render(flagged(in), flagged(tg), model::TargetPoses::Dataset);
  auto plain = net->render(s.inputs, s.targets, model::TargetPoses::Dataset);
  EXPECT_LT(test::max_abs_diff(given.render, plain.render), 1e-4);
}

TEST(Variants, PtlvsmMarksInputViewZeroAndLvsmEveryInputView) {
  torch::manual_seed(4);
  auto s = random_scene(1, 3, 1);
  for (const std::string variant : {"ptlvsm", "lvsm"}) {
    auto net = model::make_model(small_config(variant));
    net->eval();
    torch::NoGradGuard no_grad;
    model::ForwardTrace trace;
    net->render(s.inputs, s.targets, model::TargetPoses::Dataset, &trace);
    auto raw = net->tokenize(s.inputs.images);  // DINOv2 tokens before any camera is added
    for (int64_t v = 0; v < 3; ++v) {
      const bool posed = v == 0 || variant == "lvsm";
      const double diff = test::max_abs_diff(trace.input_dino_tokens.select(1, v), raw.select(1, v));
      if (posed)
        EXPECT_GT(diff, 1e-4) << variant << " view " << v;
      else
        EXPECT_EQ(diff, 0.0) << variant << " view " << v;
    }
  }
}

TEST(Variants, KeepImageTokensExtendsTheSceneLatentsWithTheEncodersImageTokens) {
  torch::manual_seed(7);
  auto config = small_config("uplvsm");
  model::UPLVSM plain(config);
  config.keep_image_tokens = true;
  model::UPLVSM kept(config);
  io::load_state_dict(*kept, io::state_dict(*plain), "plain");  // the same weights: no new parameter
  plain->eval(), kept->eval();
  torch::NoGradGuard no_grad;
  auto s = random_scene(2, 2, 3);
  auto latents = plain->encode_scene(s.inputs.images, s.inputs.fxfycxcy);
  auto scene = kept->encode_scene(s.inputs.images, s.inputs.fxfycxcy);
  const int64_t L = config.transformer.n_latent_vectors, n = (32 / config.patch_size) * (32 / config.patch_size);
  ASSERT_EQ(scene.sizes(), (std::vector<int64_t>{2, L + 2 * n, config.transformer.d}));
  EXPECT_LT(test::max_abs_diff(scene.narrow(1, 0, L), latents), 1e-6);
  auto out = kept->render(s.inputs, s.targets, model::TargetPoses::Estimator);
  EXPECT_EQ(out.render.sizes(), (std::vector<int64_t>{2, 3, 3, 32, 32}));
  EXPECT_GT(test::max_abs_diff(out.render, plain->render(s.inputs, s.targets, model::TargetPoses::Estimator).render),
            1e-6);  // the decoder now attends to the image tokens too
  auto plain_flops = train::forward_flops(small_config("uplvsm"), 1, 2, 3);
  auto kept_flops = train::forward_flops(config, 1, 2, 3);
  EXPECT_GT(kept_flops.encoder, plain_flops.encoder);  // the plain encoder's last block skips the image-token rows
  EXPECT_GT(kept_flops.decoder, plain_flops.decoder);
}

// model.encoder_latent_cameras: the encoder's second pass carries, on input views 1.., the rays of the latent poses
// the estimator reads from them in the first pass's scene; view 0 keeps the identity marker.
TEST(Variants, EncoderLatentCamerasGiveTheEncoderTheInputsLatentPoses) {
  torch::manual_seed(8);
  auto config = small_config("uplvsm");
  config.keep_image_tokens = true;
  model::UPLVSM plain(config);
  config.encoder_latent_cameras = true;
  model::UPLVSM two_pass(config);
  io::load_state_dict(*two_pass, io::state_dict(*plain), "plain");  // no new parameter
  plain->eval(), two_pass->eval();
  auto s = random_scene(2, 3, 2);
  const auto& images = s.inputs.images;
  const int64_t b = 2, H = 32, W = 32;
  // The composition by hand: the official scene, the estimator on views 1 and 2 there, the encoder again.
  auto first = plain->encode_scene(images, s.inputs.fxfycxcy);
  auto poses = plain->estimate_poses(images.narrow(1, 1, 2), first);
  auto c2w = torch::cat({geometry::identity_c2w({b, 1}, poses.options()), geometry::pose_encoding_to_c2w(poses)}, 1);
  auto expected = plain->encode_scene_with_rays(images, geometry::plucker_rays(c2w, s.inputs.fxfycxcy, H, W));
  model::ForwardTrace trace;  // keeps the second pass, the one the scene comes from
  auto scene = two_pass->encode_scene(images, s.inputs.fxfycxcy, &trace);
  EXPECT_LT(test::max_abs_diff(scene, expected), 1e-5);
  EXPECT_LT(test::max_abs_diff(trace.encoder_output, expected), 1e-5);
  EXPECT_GT(test::max_abs_diff(scene, first), 1e-4);  // the second pass is not the official scene
  // Moving a view's latent pose moves the scene: the estimator's weights get a gradient through the encoder alone.
  two_pass->train();
  two_pass->encode_scene(images, s.inputs.fxfycxcy).square().sum().backward();
  double estimator_grad = 0;
  for (const auto& p : two_pass->estimator->parameters())
    if (p.grad().defined()) estimator_grad += p.grad().abs().sum().item<double>();
  EXPECT_GT(estimator_grad, 0.0);
  {  // in bf16 training, where the estimator's heads may answer in bf16
    AutocastGuard autocast(torch::kCPU, true);
    EXPECT_EQ(two_pass->encode_scene(images, s.inputs.fxfycxcy).size(1), scene.size(1));
  }
  // One input view has no other view to place: the official scene.
  torch::NoGradGuard no_grad;
  two_pass->eval();
  EXPECT_EQ(test::max_abs_diff(two_pass->encode_scene(images.narrow(1, 0, 1), s.inputs.fxfycxcy.narrow(1, 0, 1)),
                               plain->encode_scene(images.narrow(1, 0, 1), s.inputs.fxfycxcy.narrow(1, 0, 1))),
            0.0);
  // The FLOP count has the second pass and the inputs' poses.
  auto once = train::forward_flops(small_config("uplvsm"), 1, 3, 2);
  auto two_pass_config = small_config("uplvsm");
  two_pass_config.encoder_latent_cameras = true;
  auto twice = train::forward_flops(two_pass_config, 1, 3, 2);
  EXPECT_DOUBLE_EQ(twice.encoder, 2 * once.encoder);
  EXPECT_DOUBLE_EQ(twice.estimator, 2 * once.estimator);  // 2 targets, then the 2 posed inputs
  EXPECT_GT(twice.other, once.other);
  EXPECT_DOUBLE_EQ(twice.decoder, once.decoder);
}

TEST(Variants, UplvsmTargetPoseSourcesAreOneSeam) {
  torch::manual_seed(5);
  auto config = small_config("uplvsm");
  config.pose_mapper = true;
  model::UPLVSM net(config);
  net->eval();
  auto s = random_scene(2, 2, 2);
  auto by_estimator = net->render(s.inputs, s.targets, model::TargetPoses::Estimator);
  auto legacy = net->forward(s.inputs.images, s.inputs.fxfycxcy, s.targets.images, s.targets.fxfycxcy);
  EXPECT_TRUE(torch::allclose(by_estimator.render, legacy.render));
  // The mapper starts as the identity: mapper poses equal dataset poses.
  auto by_dataset = net->render(s.inputs, s.targets, model::TargetPoses::Dataset);
  auto by_mapper = net->render(s.inputs, s.targets, model::TargetPoses::Mapper);
  EXPECT_LT(test::max_abs_diff(by_dataset.pose_enc, by_mapper.pose_enc), 1e-5);
  EXPECT_LT(test::max_abs_diff(by_dataset.render, by_mapper.render), 1e-5);
  EXPECT_LT(test::max_abs_diff(by_dataset.pose_enc, geometry::camera_control_poses(s.inputs.c2w, s.targets.c2w)), 1e-6);
  // Dataset poses need cameras; a model without a mapper says how to get one.
  auto unposed = s.targets;
  unposed.c2w = torch::Tensor();
  EXPECT_NE(test::error_of([&] { net->render(s.inputs, unposed, model::TargetPoses::Dataset); }).find("c2w"),
            std::string::npos);
  model::UPLVSM plain(small_config("uplvsm"));
  EXPECT_NE(
      test::error_of([&] { plain->render(s.inputs, s.targets, model::TargetPoses::Mapper); }).find("--stage mapper"),
      std::string::npos);
  // Gradients reach the mapper through the renderer.
  net->train();
  net->render(s.inputs, s.targets, model::TargetPoses::Mapper).render.mean().backward();
  ASSERT_TRUE(net->pose_mapper->A.grad().defined());
  EXPECT_GT(net->pose_mapper->A.grad().abs().sum().item<double>(), 0);
}

TEST(Variants, FlopCountsFollowTheArchitecture) {
  // One block: projections 2 s 4 d^2, MLP 2 s 2 d h, attention 4 s^2 d.
  EXPECT_DOUBLE_EQ(train::transformer_block_flops(10, 4, 16),
                   2.0 * 10 * 4 * 16 + 2.0 * 10 * 2 * 4 * 16 + 4.0 * 100 * 4);
  // A stack whose last block keeps 3 of 10 rows: q, k, v over all 10 there, the rest over 3.
  EXPECT_DOUBLE_EQ(train::transformer_stack_flops(2, 10, 3, 4, 16), train::transformer_block_flops(10, 4, 16) +
                                                                        2.0 * 10 * 3 * 16 + 2.0 * 3 * 16 +
                                                                        2.0 * 3 * 2 * 4 * 16 + 4.0 * 3 * 10 * 4);
  EXPECT_DOUBLE_EQ(train::transformer_stack_flops(3, 10, 10, 4, 16), 3 * train::transformer_block_flops(10, 4, 16));
  auto up = train::forward_flops(small_config("uplvsm"), 1, 2, 3);
  auto pt = train::forward_flops(small_config("ptlvsm"), 1, 2, 3);
  EXPECT_GT(up.estimator, 0);
  EXPECT_EQ(pt.estimator, 0);
  EXPECT_EQ(pt.encoder, 0);
  EXPECT_LT(pt.dinov2, up.dinov2);  // no target images through DINOv2 without the estimator
  EXPECT_GT(train::forward_flops(small_config("lvsm"), 1, 2, 3).other, pt.other);  // rays on both input views
  EXPECT_DOUBLE_EQ(train::forward_flops(small_config("uplvsm"), 2, 2, 3).total(), 2 * up.total());
}
