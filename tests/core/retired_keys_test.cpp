// core/retired_keys: files written before issue 62 (configs, checkpoints, shipped models) carry the keys of the
// levers it removed. At their old defaults they load; at any other value the error names the key, says it was
// retired and where its code and its measurements are.
#include <gtest/gtest.h>

#include <filesystem>

#include "test_util.h"
#include "uplvsm/core/config.h"
#include "uplvsm/core/retired_keys.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/safetensors.h"

using namespace uplvsm;

namespace {

// The retired keys as commit d3badc2 wrote them into every config and checkpoint: each at its default. Spelled out
// here (not read from the table) so a wrong default in the table fails this test.
nlohmann::json config_as_written_by_d3badc2() {
  auto j = config_to_json(Config());
  j["model"]["estimator_half_view"] = false;
  j["model"]["transformer"].update({{"identity_rotation_init", false},
                                    {"latent_rotation_gain", 1.0},
                                    {"latent_pivot_depth", 0.0},
                                    {"estimator_correspondence", false},
                                    {"pose_error_feedback_steps", 0}});
  j["training"].update({{"l1_loss_weight", 0.0},
                        {"ssim_loss_weight", 0.0},
                        {"ema_decay", 0.0},
                        {"rotation_equivariance_weight", 0.0},
                        {"rotation_equivariance_degrees", 10.0},
                        {"turned_view_weight", 0.0},
                        {"turned_view_degrees", 10.0},
                        {"rotation_alignment_weight", 0.0},
                        {"rotation_alignment_blur", 0.0},
                        {"latent_translation_warmup_steps", 0},
                        {"latent_translation_weight", 0.0},
                        {"init_new_blocks_identity", false},
                        {"fitted_pose_steps", 0},
                        {"fitted_pose_lr", 0.01},
                        {"fitted_pose_weight", 1.0},
                        {"render_at_fitted_poses", true}});
  j["eval"]["num_target_views"] = 3;
  return j;
}

}  // namespace

TEST(RetiredKeys, AnOldConfigWithEveryRetiredKeyAtItsDefaultLoadsAsTheDefaults) {
  const auto old = config_as_written_by_d3badc2();
  const auto c = config_from_json(old, "old.json");
  EXPECT_EQ(config_to_json(c), config_to_json(Config()));             // read as if absent
  EXPECT_FALSE(config_to_json(c)["training"].contains("ema_decay"));  // and not written again
  // An integer where the default was a float (and the reverse) is the same value.
  auto j = config_to_json(Config());
  j["training"]["turned_view_degrees"] = 10;
  j["model"]["transformer"]["pose_error_feedback_steps"] = 0.0;
  EXPECT_NO_THROW(config_from_json(j, "old.json"));
}

TEST(RetiredKeys, AnotherValueFailsNamingTheKeyTheCommitAndTheResearchLog) {
  struct Case {
    const char* section;
    const char* key;
    nlohmann::json value;
  };
  for (const auto& [section, key, value] :
       {Case{"training", "ema_decay", 0.999}, Case{"model.transformer", "latent_pivot_depth", 2.0},
        Case{"model", "estimator_half_view", true}, Case{"training", "render_at_fitted_poses", false},
        Case{"eval", "num_target_views", 6}}) {
    auto j = config_as_written_by_d3badc2();
    if (std::string(section) == "model.transformer")
      j["model"]["transformer"][key] = value;
    else
      j[section][key] = value;
    const auto msg = test::error_of([&] { config_from_json(j, "run/config.json"); });
    SCOPED_TRACE(msg);
    EXPECT_NE(msg.find(std::string("run/config.json: ") + section), std::string::npos);
    EXPECT_NE(msg.find(std::string(section) + "." + key + " was retired"), std::string::npos);
    EXPECT_NE(msg.find("d3badc2"), std::string::npos);
    EXPECT_NE(msg.find("docs/research/levers.md"), std::string::npos);
    EXPECT_NE(msg.find(value.dump()), std::string::npos);
  }
}

TEST(RetiredKeys, OnlyTheirOwnSectionAndNeverKnownKeysStayUnknown) {
  auto msg = test::error_of([] { config_from_json({{"training", {{"latent_pivot_depth", 0.0}}}}, "x.json"); });
  EXPECT_NE(msg.find("x.json: training: unknown field 'latent_pivot_depth'"), std::string::npos) << msg;
  msg = test::error_of([] { config_from_json({{"training", {{"ema_decayy", 0.0}}}}, "x.json"); });
  EXPECT_NE(msg.find("unknown field 'ema_decayy'"), std::string::npos) << msg;
  EXPECT_EQ(find_retired_key("training", "lr"), nullptr);
  ASSERT_NE(find_retired_key("training", "fitted_pose_lr"), nullptr);
  EXPECT_STREQ(find_retired_key("training", "fitted_pose_lr")->commit, "d3badc2");
}

TEST(RetiredKeys, SettingOneOnTheCommandLineSaysItWasRetired) {
  const auto msg =
      test::error_of([] { apply_config_overrides(Config(), {"training.turned_view_weight=1"}, "tiny.json"); });
  EXPECT_NE(msg.find("--set 'training.turned_view_weight=1': the config has no field"), std::string::npos) << msg;
  EXPECT_NE(msg.find("training.turned_view_weight was retired"), std::string::npos) << msg;
  EXPECT_NE(msg.find("d3badc2"), std::string::npos) << msg;
}

// A checkpoint is a config embedded in a safetensors header: one written before issue 62 loads, one trained with a
// retired lever on fails naming the file and the key.
TEST(RetiredKeys, CheckpointsWrittenBeforeLoadUnlessALeverWasOn) {
  const auto dir = test::temp_dir("retired_keys");
  auto write = [&](const std::string& name, const nlohmann::json& config) {
    const auto path = (dir / name).string();
    io::write_safetensors(path, {{"w", torch::zeros({2})}},
                          {{"format", io::kCheckpointFormat}, {"config", config.dump()}, {"state", "{\"step\": 3}"}});
    return path;
  };
  const auto old = io::read_checkpoint(write("old.safetensors", config_as_written_by_d3badc2()));
  EXPECT_EQ(config_to_json(old.config), config_to_json(Config()));
  EXPECT_EQ(old.state["step"], 3);
  auto with_ema = config_as_written_by_d3badc2();
  with_ema["training"]["ema_decay"] = 0.99;
  const auto path = write("ema.safetensors", with_ema);
  const auto msg = test::error_of([&] { io::read_checkpoint(path); });
  EXPECT_NE(msg.find(path + " (embedded config): training: 'ema_decay' is 0.99"), std::string::npos) << msg;
  EXPECT_NE(msg.find("training.ema_decay was retired"), std::string::npos) << msg;
  EXPECT_NE(msg.find("commit d3badc2"), std::string::npos) << msg;
}

// The shipped models were written before issue 62: their embedded configs carry retired keys, and they load.
TEST(RetiredKeys, TheShippedModelsCarryRetiredKeysAndLoad) {
  for (const char* name : {"demo", "demo_mapper", "demo_lvsm"}) {
    const auto path = std::string(UPLVSM_SOURCE_DIR) + "/models/" + name + ".safetensors";
    SCOPED_TRACE(path);
    std::map<std::string, std::string> metadata;
    io::read_safetensors_header(path, &metadata);
    const auto embedded = nlohmann::json::parse(metadata.at("config"));
    EXPECT_TRUE(embedded["training"].contains("turned_view_weight"));
    EXPECT_TRUE(embedded["eval"].contains("num_target_views"));
    EXPECT_NO_THROW(io::read_checkpoint(path));
  }
}
