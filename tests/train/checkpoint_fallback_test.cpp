// --resume auto after a damaged newest checkpoint (a full disk, an interrupted copy): it falls back to the newest
// checkpoint that reads, with a warning naming the bad file; a damaged file given explicitly stays an error.
#include <gtest/gtest.h>

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <sstream>

#include "train_test_util.h"
#include "uplvsm/train/checkpoint.h"
#include "uplvsm/train/trainer.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {

// Cuts a file to `keep` of its bytes, as a full disk or an interrupted copy leaves it.
void truncate_file(const std::string& path, double keep) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), {});
  in.close();
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(bytes.data(), std::streamsize(bytes.size() * keep));
}

// Captures what spdlog logs while alive.
struct LogCapture {
  std::ostringstream text;
  std::shared_ptr<spdlog::logger> previous = spdlog::default_logger();
  LogCapture() {
    spdlog::set_default_logger(
        std::make_shared<spdlog::logger>("capture", std::make_shared<spdlog::sinks::ostream_sink_mt>(text)));
  }
  ~LogCapture() { spdlog::set_default_logger(previous); }
};

// A micro run with checkpoints at steps 2, 4 and 6 (all kept).
std::string run_with_three_checkpoints(const std::string& name) {
  auto config = test::micro_config();
  config.training.train_steps = 6;
  config.training.checkpoint_every = 2;
  auto run = test::temp_dir(name).string();
  train::train(config, test::micro_run_options(run));
  return run;
}

}  // namespace

TEST(CheckpointFallback, NewestValidCheckpointSkipsDamagedOnesWithAWarning) {
  const auto run = run_with_three_checkpoints("ckpt_fallback");
  const auto dir = (fs::path(run) / "checkpoints").string();
  const auto all = train::training_checkpoints(dir);
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(fs::path(all[2]).filename(), train::checkpoint_name(6));

  truncate_file(all[2], 0.5);  // cut inside the tensor data
  truncate_file(all[1], 0.0);  // empty
  LogCapture log;
  auto ckpt = train::read_newest_valid_checkpoint(dir);
  ASSERT_TRUE(ckpt.has_value());
  EXPECT_EQ(ckpt->path, all[0]);
  EXPECT_EQ(ckpt->state.at("step").get<int64_t>(), 2);
  const auto text = log.text.str();
  EXPECT_NE(text.find(all[2]), std::string::npos) << text;  // each skipped file is named
  EXPECT_NE(text.find(all[1]), std::string::npos) << text;

  truncate_file(all[0], 0.9);
  const auto msg = test::error_of([&] { train::read_newest_valid_checkpoint(dir); });
  EXPECT_NE(msg.find("none of the 3 checkpoints"), std::string::npos) << msg;
  EXPECT_NE(msg.find(all[0]), std::string::npos) << msg;
  EXPECT_NE(msg.find("--resume none"), std::string::npos) << msg;

  EXPECT_FALSE(train::read_newest_valid_checkpoint((fs::path(run) / "no_such_dir").string()).has_value());
}

TEST(CheckpointFallback, ResumeAutoContinuesFromThePreviousCheckpointAndAnExplicitBadFileIsAnError) {
  const auto run = run_with_three_checkpoints("ckpt_resume_fallback");
  const auto all = train::training_checkpoints((fs::path(run) / "checkpoints").string());
  ASSERT_EQ(all.size(), 3u);
  truncate_file(all[2], 0.7);

  auto config = test::micro_config();
  config.training.train_steps = 6;
  config.training.checkpoint_every = 2;
  auto explicit_bad = test::micro_run_options(run);
  explicit_bad.resume = all[2];
  const auto msg = test::error_of([&] { train::train(config, explicit_bad); });
  EXPECT_NE(msg.find(all[2]), std::string::npos) << msg;

  // auto: resumes at step 4 and trains steps 5 and 6 again (rewriting the damaged checkpoint).
  LogCapture log;
  EXPECT_EQ(train::train(config, test::micro_run_options(run)).step, 6);
  EXPECT_NE(log.text.str().find("resumed from " + all[1] + " at step 4"), std::string::npos) << log.text.str();
  EXPECT_EQ(train::read_newest_valid_checkpoint((fs::path(run) / "checkpoints").string())->path, all[2]);
}

// A checkpoint's training state is read from the file: a step that is no int64 (a float-to-int cast was undefined
// behaviour, found by fuzzing the checkpoint reader) or a missing one is an error naming the field.
TEST(CheckpointFallback, TrainingStateTakesIntegersOnly) {
  const auto good = nlohmann::json{{"step", 4}, {"scheduler_step", 4}, {"param_update_step", 4}};
  EXPECT_EQ(train::TrainState::from_json(good).step, 4);
  EXPECT_EQ(train::TrainState::from_json(good).skipped_gradnorm, 0);
  auto bad = good;
  bad["step"] = 4.4e24;
  auto msg = test::error_of([&] { train::TrainState::from_json(bad); });
  EXPECT_NE(msg.find("training state step: expected an integer, got 4.4e+24"), std::string::npos) << msg;
  bad = good;
  bad["skipped_nonfinite"] = nlohmann::json::array({1});
  msg = test::error_of([&] { train::TrainState::from_json(bad); });
  EXPECT_NE(msg.find("training state skipped_nonfinite: expected an integer, got an array of 1"), std::string::npos)
      << msg;
  bad = good;
  bad.erase("scheduler_step");
  msg = test::error_of([&] { train::TrainState::from_json(bad); });
  EXPECT_NE(msg.find("training state: missing field 'scheduler_step'"), std::string::npos) << msg;
}
