#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/train/global_batch.h"

using namespace uplvsm;

TEST(GlobalBatch, WithoutAGlobalSizeTheConfigsAccumulationIsUsed) {
  TrainingConfig t;
  t.batch_size = 4;
  t.grad_accum_steps = 3;
  const auto plan = train::plan_batch(t, 2, "c.json");
  EXPECT_EQ(plan.accumulation, 3);
  EXPECT_EQ(plan.global(), 24);
}

TEST(GlobalBatch, AccumulationIsDerivedFromTheGlobalSizeAndTheRanks) {
  TrainingConfig t;
  t.batch_size = 6;
  t.global_batch_size = 48;
  for (int64_t ranks : {1, 2, 4, 8}) {
    const auto plan = train::plan_batch(t, ranks, "c.json");
    EXPECT_EQ(plan.accumulation, 8 / ranks) << ranks;
    EXPECT_EQ(plan.global(), 48) << ranks;
  }
  t.grad_accum_steps = 4;  // stated and consistent on 2 ranks
  EXPECT_EQ(train::plan_batch(t, 2, "c.json").accumulation, 4);
}

TEST(GlobalBatch, ASizeThatDoesNotDivideIsAnErrorNamingTheNumbers) {
  TrainingConfig t;
  t.batch_size = 16;
  t.global_batch_size = 128;
  auto msg = test::error_of([&] { train::plan_batch(t, 3, "paper.json"); });
  for (const char* part : {"paper.json", "training.global_batch_size = 128", "batch_size (16)", "3 rank(s) = 48"})
    EXPECT_NE(msg.find(part), std::string::npos) << msg;
  msg = test::error_of([&] { train::plan_batch(t, 16, "paper.json"); });  // 256 per micro-batch: more than 128
  EXPECT_NE(msg.find("= 256"), std::string::npos) << msg;
  t.grad_accum_steps = 2;  // contradicts the 8 that one process needs
  msg = test::error_of([&] { train::plan_batch(t, 1, "paper.json"); });
  EXPECT_NE(msg.find("training.grad_accum_steps = 2 contradicts"), std::string::npos) << msg;
  EXPECT_NE(msg.find("needs 8"), std::string::npos) << msg;
}
