// The single-model analyses through study:: without the binary, on a micro UP-LVSM and the micro rooms: the probe's
// accuracies and files, the sensitivity summary, t-SNE's points and the attention maps, each where it says.
#include "uplvsm/study/pose_studies.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "train/train_test_util.h"
#include "uplvsm/model/model_factory.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {

model::UPLVSM study_net() {
  torch::manual_seed(21);
  return model::require_uplvsm(model::make_model(test::micro_model()), "test");
}

study::PoseStudyOptions study_options(const std::string& out) {
  study::PoseStudyOptions o;
  o.data = test::micro_dataset();
  o.out = out;
  o.gap = 4;
  o.iterations = 20;
  o.checkpoint = "micro";
  return o;
}

}  // namespace

TEST(PoseStudies, ProbeSensitivityAndTsneWriteWhatTheyReport) {
  const auto dir = test::temp_dir("pose_studies");
  auto net = study_net();
  const auto config = test::micro_config();
  auto o = study_options((dir / "probe").string());
  const auto probe = study::run_pose_probe(net, config, o);
  EXPECT_EQ(probe.train_views, 6u * 4u);  // six scenes, frames 1..4 of {0, 4}: the first context view excluded
  EXPECT_EQ(probe.test_views, 2u * 4u);
  std::ifstream in(fs::path(o.out) / "probe.json");
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j.at("train_views"), 24);
  EXPECT_EQ(j.at("mlp").dump(), study::to_json(probe.mlp).dump());
  for (const auto* file : {"pairs_train.csv", "pairs_test.csv"}) EXPECT_TRUE(fs::exists(fs::path(o.out) / file));

  o.out = (dir / "sensitivity").string();
  const auto summary = study::run_pose_sensitivity(net, config, o);
  EXPECT_EQ(summary.at("target_poses"), "estimator");  // auto: UP-LVSM's protocol
  EXPECT_TRUE(fs::exists(fs::path(o.out) / "views.csv"));
  EXPECT_TRUE(fs::exists(fs::path(o.out) / "sensitivity.json"));

  o.out = (dir / "tsne").string();
  o.perplexity = 3;
  const auto t = study::run_tsne(net, config, o);
  EXPECT_EQ(t.pairs, 8);
  EXPECT_TRUE(fs::exists(t.png));
  std::ifstream csv(fs::path(o.out) / "tsne.csv");
  int lines = 0;
  for (std::string line; std::getline(csv, line);) ++lines;
  EXPECT_EQ(lines, 1 + 2 * 8);  // header, then each pair's latent and real point
}

TEST(PoseStudies, AttentionDrawsTheIndexScenesAtTheCentrePatch) {
  const auto dir = test::temp_dir("attention_study");
  auto net = study_net();
  study::AttentionOptions o;
  o.data = test::micro_dataset();
  o.out = dir.string();
  o.scenes = 2;
  const auto drawn = study::run_attention(net, test::micro_config(), o);
  ASSERT_EQ(drawn.size(), 2u);
  EXPECT_EQ(drawn[0].row, 2);              // a 4 x 4 patch grid
  EXPECT_GT(drawn[0].attention_sum, 0.0);  // its share of view 1's patch's attention
  EXPECT_LE(drawn[0].attention_sum, 1.0 + 1e-5);
  EXPECT_TRUE(fs::exists(drawn[1].png));
  EXPECT_TRUE(fs::exists(dir / "attention.json"));
}
