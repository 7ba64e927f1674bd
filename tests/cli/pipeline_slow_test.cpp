// The demo's pipeline through the binary at micro scale: make-dataset -> train -> (kill, resume) -> eval -> render
// -> report, checking each step's files.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "train/train_test_util.h"

namespace fs = std::filesystem;

namespace {
using uplvsm::test::run_cli;

// A micro built-in dataset and a 12-step run of it (stopped at step 7, then resumed), made once per test process
// (ctest runs each test alone) for the tests below.
struct TrainedPipeline {
  fs::path dir;
  std::string cfg, data, run;
  int dataset_status = -1, first_status = -1, resume_status = -1;
  std::string resume_output;
};

const TrainedPipeline& trained_pipeline() {
  static TrainedPipeline p = [] {
    TrainedPipeline t;
    t.dir = uplvsm::test::temp_dir("pipeline");
    auto config = uplvsm::test::micro_config();
    config.training.train_steps = 12;
    config.training.checkpoint_every = 5;
    config.dataset.num_train_scenes = 4;
    config.dataset.num_test_scenes = 3;
    config.dataset.render_height = 36;
    config.dataset.render_width = 64;
    config.dataset.frames_per_scene = 12;
    config.dataset.eval_gap = 6;
    std::ofstream(t.dir / "micro.json") << uplvsm::config_to_json(config).dump(2);
    t.cfg = (t.dir / "micro.json").string();
    t.data = (t.dir / "data").string();
    t.run = (t.dir / "run").string();
    t.dataset_status = run_cli("make-dataset --config " + t.cfg + " --out " + t.data);
    t.first_status = run_cli("train --config " + t.cfg + " --data " + t.data + " --run " + t.run + " --stop-after 7");
    t.resume_status = run_cli("train --config " + t.cfg + " --data " + t.data + " --run " + t.run, &t.resume_output);
    return t;
  }();
  return p;
}
}  // namespace

TEST(Pipeline, DatasetTrainEvalRenderReport) {
  const auto& p = trained_pipeline();
  const fs::path& dir = p.dir;
  const std::string &data = p.data, &run = p.run;
  ASSERT_EQ(p.dataset_status, 0);
  EXPECT_TRUE(fs::exists(dir / "data/train/index.json"));
  EXPECT_TRUE(fs::exists(dir / "data/evaluation_index.json"));
  ASSERT_EQ(p.first_status, 0);
  ASSERT_EQ(p.resume_status, 0) << p.resume_output;
  EXPECT_NE(p.resume_output.find("resumed"), std::string::npos) << p.resume_output;
  EXPECT_NE(p.resume_output.find("trained to step 12"), std::string::npos) << p.resume_output;

  std::string out;
  ASSERT_EQ(run_cli("eval --checkpoint " + run + " --data " + data + " --out " + (dir / "eval").string(), &out), 0);
  EXPECT_NE(out.find("copy nearest"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(dir / "eval/metrics.json"));
  EXPECT_TRUE(fs::exists(dir / "eval/per_scene.csv"));

  ASSERT_EQ(run_cli("render --checkpoint " + run + " --data " + data + " --frames 6 --out " + (dir / "video").string()),
            0);
  EXPECT_TRUE(fs::exists(dir / "video/videos.json"));

  ASSERT_EQ(run_cli("report --run " + run + " --eval " + (dir / "eval").string() + " --video " +
                        (dir / "video").string() + " --out " + (dir / "report").string(),
                    &out),
            0);
  EXPECT_TRUE(fs::exists(dir / "report/index.html"));
  EXPECT_TRUE(fs::exists(dir / "report/training_curve.png"));
  EXPECT_NE(out.find("held-out PSNR"), std::string::npos) << out;

  // Bring-your-own photos: two frames written as PNG files.
  ASSERT_EQ(run_cli("render --checkpoint " + run + " --images " + (dir / "eval/scenes").string() +
                        "/missing.png x.png --out " + (dir / "byo").string(),
                    &out) != 0,
            true);
  EXPECT_NE(out.find("missing.png"), std::string::npos) << out;
}

// Camera control: the mapper stage from the trained run, evaluation from dataset cameras through the mapper, and
// an orbit video through it.
TEST(Pipeline, CameraControlStage) {
  const auto& p = trained_pipeline();
  const fs::path& dir = p.dir;
  const std::string &cfg = p.cfg, &data = p.data, &run = p.run;
  ASSERT_EQ(p.resume_status, 0) << p.resume_output;
  std::string out;
  auto mapper_run = (dir / "mapper_run").string();
  ASSERT_EQ(run_cli("train --stage mapper --init " + run + " --config " + cfg + " --data " + data + " --run " +
                        mapper_run + " --steps 4",
                    &out),
            0);
  EXPECT_NE(out.find("pose mapper: least-squares fit"), std::string::npos) << out;
  ASSERT_EQ(run_cli("eval --checkpoint " + mapper_run + " --target-poses mapper --data " + data + " --out " +
                        (dir / "eval_mapper").string(),
                    &out),
            0);
  EXPECT_NE(out.find("uplvsm (mapper)"), std::string::npos) << out;
  ASSERT_EQ(run_cli("render --checkpoint " + mapper_run + " --data " + data +
                    " --trajectory orbit --frames 4 --side-by-side "
                    "--out " +
                    (dir / "orbit").string()),
            0);
  EXPECT_TRUE(fs::exists(dir / "orbit/videos.json"));
  // The plain model has no mapper: a camera path is refused with the way to get one.
  ASSERT_NE(run_cli("render --checkpoint " + run + " --data " + data + " --trajectory dolly --out " +
                        (dir / "dolly").string(),
                    &out),
            0);
  EXPECT_NE(out.find("--stage mapper"), std::string::npos) << out;
}

// The pose studies on the trained run (tiny budgets).
TEST(Pipeline, PoseStudies) {
  const auto& p = trained_pipeline();
  const fs::path& dir = p.dir;
  const std::string &cfg = p.cfg, &data = p.data, &run = p.run;
  ASSERT_EQ(p.resume_status, 0) << p.resume_output;
  std::string out;
  ASSERT_EQ(run_cli("study pose-probe --checkpoint " + run + " --data " + data + " --gap 5 --iterations 50 --out " +
                        (dir / "probe").string(),
                    &out),
            0);
  EXPECT_NE(out.find("trans@0.1/0.2/0.3"), std::string::npos) << out;
  EXPECT_NE(out.find("  mean    trans@0.1"), std::string::npos) << out;  // the floor the probes are read against
  ASSERT_TRUE(fs::exists(dir / "probe/probe.json"));
  const auto probe = nlohmann::json::parse(std::ifstream(dir / "probe/probe.json"));
  for (const char* key : {"mlp", "linear", "mean_pose"}) EXPECT_TRUE(probe.contains(key)) << key;
  ASSERT_EQ(run_cli("study tsne --checkpoint " + run + " --data " + data +
                        " --gap 5 --perplexity 3 --iterations 100 --out " + (dir / "tsne").string(),
                    &out),
            0);
  EXPECT_TRUE(fs::exists(dir / "tsne/tsne.png"));
  EXPECT_TRUE(fs::exists(dir / "tsne/tsne.csv"));
  ASSERT_EQ(run_cli("study attention --checkpoint " + run + " --data " + data + " --scenes 2 --patch 1 2 --out " +
                        (dir / "attention").string(),
                    &out),
            0);
  EXPECT_NE(out.find("patch (1, 2)"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(dir / "attention/attention.json"));
  EXPECT_NE(run_cli("study attention --checkpoint " + run + " --data " + data + " --patch 9 0 --out " +
                        (dir / "attention_bad").string(),
                    &out),
            0);
  EXPECT_NE(out.find("outside view 1's 4x4 patch grid"), std::string::npos) << out;
}

// The tokenizer's self-supervised stage through the binary, then a main-stage run that starts from its file.
TEST(Pipeline, TokenizerStageThenInit) {
  const auto& p = trained_pipeline();
  const fs::path& dir = p.dir;
  const std::string &cfg = p.cfg, &data = p.data;
  ASSERT_EQ(p.dataset_status, 0);
  std::string out;
  const auto tokenizer = (dir / "tokenizer").string();
  ASSERT_EQ(
      run_cli("train --stage tokenizer --config " + cfg + " --data " + data + " --run " + tokenizer + " --steps 6",
              &out),
      0);
  EXPECT_NE(out.find("tokenizer pretrained for 6 steps"), std::string::npos) << out;
  ASSERT_TRUE(fs::exists(dir / "tokenizer/tokenizer.safetensors"));
  ASSERT_EQ(run_cli("train --config " + cfg + " --data " + data + " --run " + (dir / "from_tokenizer").string() +
                        " --init " + tokenizer + "/tokenizer.safetensors --steps 2",
                    &out),
            0);
  EXPECT_NE(out.find("initialised from DINOv2 (Meta names) weights"), std::string::npos) << out;
}
