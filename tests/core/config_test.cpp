#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "test_util.h"
#include "uplvsm/core/config.h"

using namespace uplvsm;

TEST(Config, ShippedConfigsLoadAndRoundTrip) {
  int configs = 0;
  for (const auto& entry : std::filesystem::directory_iterator(std::string(UPLVSM_SOURCE_DIR) + "/configs")) {
    if (entry.path().extension() != ".json") continue;
    ++configs;
    const std::string name = entry.path().stem().string();
    SCOPED_TRACE(name);
    auto c = load_config(entry.path().string());
    EXPECT_EQ(c.name, name);
    auto again = config_from_json(config_to_json(c));
    EXPECT_EQ(config_to_json(again), config_to_json(c));
  }
  EXPECT_GE(configs, 10);
  EXPECT_LE(configs, 16);  // the paper's, the tiny family and the shipped chain (issue 62: lab configs retired)
  auto paper = load_config(std::string(UPLVSM_SOURCE_DIR) + "/configs/paper_x224.json");
  EXPECT_EQ(paper.model.transformer.d, 768);
  EXPECT_EQ(paper.model.transformer.decoder_n_layer, 14);
  EXPECT_EQ(paper.model.transformer.n_latent_vectors, 1024);
  EXPECT_EQ(paper.model.dinov2.num_register_tokens, 4);
}

// "extends": the base's keys, this file's over them section by section; the name is this file's (else its stem);
// a chain resolves, a cycle, a missing base or one that is no regular file is an error naming the file.
TEST(Config, ExtendsTakesTheBaseAndWritesTheDifferencesOverIt) {
  const auto dir = test::temp_dir("config_extends");
  auto write = [&](const std::string& name, const nlohmann::json& j) { std::ofstream(dir / name) << j.dump(); };
  write("base.json",
        {{"name", "base"},
         {"model", {{"keep_image_tokens", true}, {"transformer", {{"n_latent_vectors", 64}, {"depth_init", true}}}}},
         {"training", {{"lr", 1e-3}, {"warmup", 100}}}});
  write("child.json", {{"name", "child"}, {"extends", "base.json"}, {"training", {{"lr", 3e-4}}}});
  write("grandchild.json", {{"extends", "child.json"}, {"model", {{"transformer", {{"n_latent_vectors", 32}}}}}});
  const auto base = load_config((dir / "base.json").string());
  const auto child = load_config((dir / "child.json").string());
  EXPECT_EQ(child.name, "child");
  EXPECT_DOUBLE_EQ(child.training.lr, 3e-4);
  EXPECT_EQ(child.training.warmup, 100);  // from the base, beside the overridden key
  EXPECT_TRUE(child.model.keep_image_tokens);
  EXPECT_TRUE(child.model.transformer.depth_init);
  EXPECT_EQ(base.name, "base");
  const auto grand = load_config((dir / "grandchild.json").string());
  EXPECT_EQ(grand.name, "grandchild");  // never inherited: the file's stem
  EXPECT_EQ(grand.model.transformer.n_latent_vectors, 32);
  EXPECT_TRUE(grand.model.transformer.depth_init);  // a section merged key by key
  EXPECT_DOUBLE_EQ(grand.training.lr, 3e-4);
  auto error_of = [&](const std::string& name) { return test::error_of([&] { load_config((dir / name).string()); }); };
  write("loop_a.json", {{"extends", "loop_b.json"}});
  write("loop_b.json", {{"extends", "loop_a.json"}});
  EXPECT_NE(error_of("loop_a.json").find("cycle"), std::string::npos) << error_of("loop_a.json");
  write("missing.json", {{"extends", "nowhere.json"}});
  EXPECT_NE(error_of("missing.json").find("nowhere.json"), std::string::npos) << error_of("missing.json");
  write("device.json", {{"extends", "/dev/zero"}});
  EXPECT_NE(error_of("device.json").find("not a config file"), std::string::npos) << error_of("device.json");
  std::ofstream(dir / "array.json") << "[1, 2]";
  write("on_array.json", {{"extends", "array.json"}});
  EXPECT_NE(error_of("on_array.json").find("array.json: expected a JSON object"), std::string::npos);
  write("bad.json", {{"extends", 3}});
  EXPECT_NE(error_of("bad.json").find("'extends' must be a config file name"), std::string::npos);
  write("typo.json", {{"extends", "base.json"}, {"training", {{"lrr", 1}}}});
  EXPECT_NE(error_of("typo.json").find("unknown field 'lrr'"), std::string::npos) << error_of("typo.json");
  // The shipped variants hold only their differences.
  const auto configs = std::string(UPLVSM_SOURCE_DIR) + "/configs/";
  const auto lvsm = load_config(configs + "tiny_lvsm.json"), ptlvsm = load_config(configs + "tiny_ptlvsm.json");
  auto as_lvsm = ptlvsm;
  as_lvsm.model.variant = Variant::LVSM, as_lvsm.name = lvsm.name;
  EXPECT_EQ(config_to_json(as_lvsm), config_to_json(lvsm));
  test::remove_tree(dir);
}

TEST(Config, UnknownFieldIsAnErrorNamingThePath) {
  nlohmann::json j = {{"model", {{"transformer", {{"dd", 3}}}}}};
  try {
    config_from_json(j, "x.json");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("x.json: model.transformer: unknown field 'dd'"), std::string::npos)
        << e.what();
  }
}

// Files written until d3badc2 carry training.pose_noise_variance (N(0, value) before the scene normalisation): at 0
// they read as clean cameras; any other value is refused with the new key, since it has no equal in the official knob.
TEST(Config, OldPoseNoiseVarianceReadsAtZeroAndIsRefusedOtherwise) {
  nlohmann::json j = {{"training", {{"pose_noise_variance", 0}}}};
  EXPECT_EQ(config_from_json(j, "old.json").training.pose_noise_std, 0);
  j["training"]["pose_noise_variance"] = 0.01;
  try {
    config_from_json(j, "old.json");
    FAIL();
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    for (const auto* needle : {"old.json", "training.pose_noise_variance", "training.pose_noise_std", "d3badc2"})
      EXPECT_NE(what.find(needle), std::string::npos) << what;
  }
  j["training"] = {{"pose_noise_std", 0.1}};
  EXPECT_EQ(config_from_json(j, "new.json").training.pose_noise_std, 0.1);
  j["training"] = {{"pose_noise_std", -0.1}};
  EXPECT_THROW(config_from_json(j, "new.json"), std::runtime_error);
}

TEST(Config, CommandLineOverridesSetFieldsAndNameTheirMistakes) {
  const auto tiny = load_config(std::string(UPLVSM_SOURCE_DIR) + "/configs/tiny.json");
  auto c = apply_config_overrides(tiny,
                                  {"training.warmup=500", "model.transformer.n_latent_vectors=64", "training.amp=bf16",
                                   "dataset.square_crop=false", "training.lr=3e-4"},
                                  "tiny.json");
  EXPECT_EQ(c.training.warmup, 500);
  EXPECT_EQ(c.model.transformer.n_latent_vectors, 64);
  EXPECT_EQ(c.training.amp, Amp::Bf16);
  EXPECT_FALSE(c.dataset.square_crop);
  EXPECT_DOUBLE_EQ(c.training.lr, 3e-4);
  EXPECT_EQ(c.training.batch_size, tiny.training.batch_size);  // untouched
  auto expect_error = [&](const std::string& assignment, const std::string& needle) {
    try {
      apply_config_overrides(tiny, {assignment}, "tiny.json");
      FAIL() << assignment;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error("training.warmpu=5", "no field 'training.warmpu'");
  expect_error("training", "expected section.field=value");
  expect_error("model.transformer=3", "is a section");
  expect_error("training.amp=fp8", "training.amp must be");
  expect_error("training.warmup=lots", "training");  // a string where a number is expected
}

// The string choices are parsed once into enums; JSON keeps their names, so a run's config.json reads as before.
TEST(Config, ChoicesAreEnumsWrittenByName) {
  auto c = config_from_json(
      {{"model", {{"variant", "lvsm"}}}, {"training", {{"amp", "bf16"}, {"target_poses", "dataset"}}}}, "choices.json");
  EXPECT_EQ(c.model.variant, Variant::LVSM);
  EXPECT_EQ(c.training.amp, Amp::Bf16);
  EXPECT_EQ(c.training.target_poses, TargetPoses::Dataset);
  const auto j = config_to_json(c);
  EXPECT_EQ(j["model"]["variant"], "lvsm");
  EXPECT_EQ(j["training"]["amp"], "bf16");
  EXPECT_EQ(j["training"]["target_poses"], "dataset");
  for (auto v : {Variant::UPLVSM, Variant::PTLVSM, Variant::LVSM}) EXPECT_EQ(parse_variant(to_string(v)), v);
  for (auto a : {Amp::None, Amp::Bf16}) EXPECT_EQ(parse_amp(to_string(a)), a);
  for (auto t : {TargetPoses::Auto, TargetPoses::Estimator, TargetPoses::Mapper, TargetPoses::Dataset})
    EXPECT_EQ(parse_target_poses(to_string(t)), t);
  auto message = [](const nlohmann::json& j) {
    try {
      config_from_json(j, "bad.json");
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message({{"model", {{"variant", "gpt"}}}}),
            "bad.json: model.variant must be 'uplvsm', 'ptlvsm' or 'lvsm', got 'gpt'");
  EXPECT_EQ(message({{"training", {{"amp", "fp16"}}}}), "bad.json: training.amp must be 'none' or 'bf16', got 'fp16'");
  EXPECT_EQ(message({{"training", {{"target_poses", "sfm"}}}}),
            "bad.json: training.target_poses must be 'auto', 'estimator', 'mapper' or 'dataset', got 'sfm'");
  EXPECT_NE(message({{"training", {{"amp", 16}}}}).find("training.amp: wrong type"), std::string::npos);
}

TEST(Config, InconsistentSizesAreRejected) {
  nlohmann::json j = {{"model", {{"image_size", 100}, {"patch_size", 14}}}};
  EXPECT_THROW(config_from_json(j, "bad.json"), std::runtime_error);
  nlohmann::json k = {{"model", {{"transformer", {{"d", 64}}}}}};  // dinov2 width stays 768
  try {
    config_from_json(k, "bad.json");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("embed_dim"), std::string::npos);
  }
  nlohmann::json t = {{"training", {{"batch_size", "eight"}}}};
  EXPECT_THROW(config_from_json(t, "bad.json"), std::runtime_error);
}

TEST(Config, TokenizerAndDatasetKnobsAreValidated) {
  auto message = [](const nlohmann::json& j) { return test::error_of([&] { config_from_json(j, "bad.json"); }); };
  auto msg = message({{"model", {{"dinov2", {{"pos_embed_init", "random"}}}}}});
  EXPECT_NE(msg.find("pos_embed_init must be 'normal' or 'sincos', got 'random'"), std::string::npos) << msg;
  nlohmann::json narrow;
  narrow["model"]["transformer"] = {{"d", 6}, {"d_head", 3}};
  narrow["model"]["dinov2"] = {{"embed_dim", 6}, {"num_heads", 2}, {"pos_embed_init", "sincos"}};
  msg = message(narrow);
  EXPECT_NE(msg.find("needs embed_dim divisible by 4"), std::string::npos) << msg;
  msg = message({{"dataset", {{"texture_scale", 0}}}});
  EXPECT_NE(msg.find("dataset.texture_scale must be > 0"), std::string::npos) << msg;
  EXPECT_NO_THROW(config_from_json({{"model", {{"dinov2", {{"pos_embed_init", "sincos"}}}}}}, "ok.json"));
}

// The paper's recipe (official config/uplvsm_x{224,518}.yaml: use_amp, amp_dtype bf16, use_tf32) trains under bf16
// autocast with TF32 on CUDA; the other configs keep fp32 unless they say otherwise.
TEST(Config, PaperConfigsTrainInBf16WithTf32) {
  for (const char* name : {"paper_x224", "paper_x518"}) {
    const auto c = load_config(std::string(UPLVSM_SOURCE_DIR) + "/configs/" + name + ".json");
    EXPECT_EQ(c.training.amp, Amp::Bf16) << name;
    EXPECT_TRUE(c.training.tf32) << name;
  }
  const auto defaults = config_from_json(nlohmann::json::object(), "ok");
  EXPECT_FALSE(defaults.training.tf32);
  EXPECT_TRUE(config_from_json({{"training", {{"tf32", true}}}}, "ok").training.tf32);
  EXPECT_EQ(config_to_json(config_from_json({{"training", {{"tf32", true}}}}, "ok"))["training"]["tf32"], true);
}

// grad_clip_norm 0 is the official "no clipping" (train_step); a negative or non-finite one is an error.
TEST(Config, GradClipNormIsZeroOrPositive) {
  auto message = [](const nlohmann::json& j) { return test::error_of([&] { config_from_json(j, "bad.json"); }); };
  EXPECT_EQ(config_from_json({{"training", {{"grad_clip_norm", 0}}}}, "ok").training.grad_clip_norm, 0.0);
  for (double bad : {-1.0, std::nan("")})
    EXPECT_NE(message({{"training", {{"grad_clip_norm", bad}}}})
                  .find("training.grad_clip_norm must be a finite "
                        "number >= 0"),
              std::string::npos)
        << bad;
  EXPECT_NE(message({{"training", {{"allowed_gradnorm_factor", 0}}}}).find("allowed_gradnorm_factor must be"),
            std::string::npos);
}

TEST(Config, GradientDifferenceWeightIsCheckedAndRoundTrips) {
  const auto ok = config_from_json({{"training", {{"gradient_difference_weight", 0.2}}}}, "ok");
  EXPECT_EQ(ok.training.gradient_difference_weight, 0.2);
  EXPECT_EQ(config_to_json(ok)["training"]["gradient_difference_weight"].get<double>(), 0.2);
  EXPECT_EQ(Config().training.gradient_difference_weight, 0.0);  // off by default
  const auto msg = test::error_of([] {
    config_from_json({{"training", {{"gradient_difference_weight", -0.1}}}}, "b");
  });
  EXPECT_NE(msg.find("training.gradient_difference_weight must be a finite number >= 0"), std::string::npos) << msg;
}

TEST(Config, EncoderLatentCamerasNeedTheUplvsmEstimator) {
  auto message = [](const nlohmann::json& j) { return test::error_of([&] { config_from_json(j, "bad.json"); }); };
  EXPECT_TRUE(config_from_json({{"model", {{"encoder_latent_cameras", true}}}}, "ok").model.encoder_latent_cameras);
  const auto msg = message({{"model", {{"variant", "ptlvsm"}, {"encoder_latent_cameras", true}}},
                            {"training", {{"target_poses", "dataset"}}}});
  EXPECT_NE(msg.find("model.encoder_latent_cameras: only the uplvsm variant"), std::string::npos) << msg;
}

TEST(Config, CurriculumAndRotationOnlyCameraReadAndCheck) {
  auto c = config_from_json({{"training", {{"frame_dist_curriculum_steps", 2000}}},
                             {"model", {{"transformer", {{"rotation_only_latent_camera", true}}}}}},
                            "ok.json");
  EXPECT_EQ(c.training.frame_dist_curriculum_steps, 2000);
  EXPECT_TRUE(c.model.transformer.rotation_only_latent_camera);
  EXPECT_FALSE(Config().model.transformer.rotation_only_latent_camera);
  const auto msg = test::error_of([] {
    config_from_json({{"training", {{"frame_dist_curriculum_steps", -1}}}}, "bad.json");
  });
  EXPECT_NE(msg.find("bad.json"), std::string::npos) << msg;
  EXPECT_NE(msg.find("training.frame_dist_curriculum_steps must be >= 0"), std::string::npos) << msg;
}

// Equal frame distances cannot train with the official view selector (it skips every scene): refused when read.
TEST(Config, EqualMinAndMaxFrameDistIsRefused) {
  const auto msg = test::error_of([] {
    config_from_json({{"training", {{"min_frame_dist", 8}, {"max_frame_dist", 8}}}}, "bad.json");
  });
  EXPECT_NE(msg.find("bad.json"), std::string::npos) << msg;
  EXPECT_NE(msg.find("training.max_frame_dist must be greater than min_frame_dist"), std::string::npos) << msg;
  EXPECT_NO_THROW(config_from_json({{"training", {{"min_frame_dist", 8}, {"max_frame_dist", 9}}}}, "ok.json"));
}

TEST(Config, DiagnosticModelSwitchesNameWhatTheyNeed) {
  auto message = [](const nlohmann::json& j) { return test::error_of([&] { config_from_json(j, "bad.json"); }); };
  // The LVSM encoder-decoder diagnostic (issue 70) is retired: a checkpoint of it says where its code is.
  auto msg = message({{"model", {{"encoder_cameras", true}}}, {"training", {{"target_poses", "dataset"}}}});
  EXPECT_NE(msg.find("model.encoder_cameras was retired"), std::string::npos) << msg;
  EXPECT_NE(msg.find("8ca59b4"), std::string::npos) << msg;
  EXPECT_FALSE(config_from_json({{"model", {{"encoder_cameras", false}}}}, "old.json").model.keep_image_tokens);
  msg = message({{"model", {{"variant", "lvsm"}, {"keep_image_tokens", true}}}});
  EXPECT_NE(msg.find("model.keep_image_tokens: only the uplvsm variant"), std::string::npos) << msg;
}

// Fuzzing found 4.4e24 as an integer field to be undefined behaviour (a float-to-int cast); fractions were cut.
TEST(Config, IntegerFieldsTakeIntegersOnly) {
  auto message = [](const nlohmann::json& j) { return test::error_of([&] { config_from_json(j, "bad.json"); }); };
  auto msg = message({{"training", {{"warmup", 4.4e24}}}});
  EXPECT_NE(msg.find("bad.json: training.warmup: expected an integer, got 4.4e+24"), std::string::npos) << msg;
  msg = message({{"model", {{"transformer", {{"d", 95.5}}}}}});
  EXPECT_NE(msg.find("model.transformer.d: expected an integer, got 95.5"), std::string::npos) << msg;
  msg = message({{"training", {{"seed", nlohmann::json::parse("18446744073709551615")}}}});
  EXPECT_NE(msg.find("training.seed: expected an integer"), std::string::npos) << msg;
  msg = message({{"training", {{"batch_size", nlohmann::json::array({1, 2})}}}});
  EXPECT_NE(msg.find("training.batch_size: expected an integer, got an array of 2"), std::string::npos) << msg;
}

TEST(Config, MissingOrInvalidFile) {
  EXPECT_THROW(load_config("/nonexistent/config.json"), std::runtime_error);
  auto dir = test::temp_dir("config");
  std::ofstream(dir / "broken.json") << "{ not json";
  try {
    load_config((dir / "broken.json").string());
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("broken.json"), std::string::npos);
  }
}
