// `uplvsm export`: a run's latest checkpoint -> a weights-only file that loads like it, and of a run that keeps a
// weight average (training.ema_decay), the average.
#include <gtest/gtest.h>

#include <filesystem>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/model/checkpoint_io.h"

using namespace uplvsm;

namespace {
const std::string kExportConfigs = std::string(UPLVSM_SOURCE_DIR) + "/configs/";
}

TEST(ExportCli, WritesTheWeightsWithoutOptimiserStateAndSaysWhenTheyAreTheAverage) {
  const auto dir = test::temp_dir("cli_export");
  const auto train = [&](const std::string& run, const std::string& extra) {
    return test::run_cli("train --config " + kExportConfigs + "tiny.json --data " + test::micro_dataset() + " --run " +
                         (dir / run).string() + " --steps 2 --threads 1" + extra);
  };
  ASSERT_EQ(train("plain", ""), 0);
  ASSERT_EQ(train("averaged", " --set training.ema_decay=0.9"), 0);
  for (const std::string run : {"plain", "averaged"}) {
    std::string out;
    const auto file = (dir / (run + ".safetensors")).string();
    ASSERT_EQ(test::run_cli("export --checkpoint " + (dir / run).string() + " --out " + file, &out), 0);
    EXPECT_EQ(out.find("weight average") != std::string::npos, run == "averaged") << out;
    const auto exported = model::read_checkpoint(file), source = model::read_checkpoint((dir / run).string());
    EXPECT_TRUE(exported.optimizer.empty());
    ASSERT_EQ(exported.model.size(), source.model.size());
    for (const auto& [k, v] : source.model) EXPECT_TRUE(torch::equal(v, exported.model.at(k))) << run << " " << k;
  }
}
