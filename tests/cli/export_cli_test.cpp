// `uplvsm export`: a run's latest checkpoint -> a weights-only file that loads like it.
#include <gtest/gtest.h>

#include <filesystem>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/io/checkpoint_io.h"

using namespace uplvsm;

namespace {
const std::string kExportConfigs = std::string(UPLVSM_SOURCE_DIR) + "/configs/";
}

TEST(ExportCli, WritesTheWeightsWithoutOptimiserState) {
  const auto dir = test::temp_dir("cli_export");
  const auto run = (dir / "run").string(), file = (dir / "weights.safetensors").string();
  ASSERT_EQ(test::run_cli("train --config " + kExportConfigs + "tiny.json --data " + test::micro_dataset() + " --run " +
                          run + " --steps 2 --threads 1"),
            0);
  std::string out;
  ASSERT_EQ(test::run_cli("export --checkpoint " + run + " --out " + file, &out), 0);
  EXPECT_NE(out.find("optimiser tensors left out"), std::string::npos) << out;
  const auto exported = io::read_checkpoint(file), source = io::read_checkpoint(run);
  EXPECT_TRUE(exported.optimizer.empty());
  EXPECT_FALSE(source.optimizer.empty());
  ASSERT_EQ(exported.model.size(), source.model.size());
  for (const auto& [k, v] : source.model) EXPECT_TRUE(torch::equal(v, exported.model.at(k))) << k;
}
