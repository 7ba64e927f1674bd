// `uplvsm convert --verify` (model/round_trip_check.h): a checkpoint that reads back as written passes with a finite
// forward pass; one whose tensors differ from the model it was written from is named.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/round_trip_check.h"

using namespace uplvsm;

TEST(RoundTripCheck, PassesAWrittenModelAndNamesAChangedTensor) {
  torch::manual_seed(1);
  const auto config = test::micro_config();
  auto net = model::make_model(config.model);
  const auto path = (test::temp_dir("round_trip_check") / "m.safetensors").string();
  io::write_checkpoint(path, config, {{"step", 0}}, io::state_dict(*net), {});
  const auto r = model::check_round_trip(path, *net, torch::kCPU);
  EXPECT_EQ(r.tensors, static_cast<int64_t>(io::state_dict(*net).size()));
  EXPECT_EQ(r.image_size, config.model.image_size);
  EXPECT_EQ(r.pose.size(), 7u);
  EXPECT_TRUE(std::isfinite(r.render_mean));
  {
    torch::NoGradGuard no_grad;
    net->parameters().front().add_(1.0);
  }
  EXPECT_THROW(model::check_round_trip(path, *net, torch::kCPU), std::runtime_error);
  test::remove_tree(std::filesystem::path(path).parent_path());
}
