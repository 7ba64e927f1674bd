// A fitted pose mapper travels apart from its model (model/pose_mapper_file.h over io/pose_mapper_file.h): written,
// read back and attached only to the model it was fitted to; a file that is no mapper, or half a mapper, is named.
#include <gtest/gtest.h>

#include <fstream>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/io/pose_mapper_file.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/pose_mapper_file.h"

using namespace uplvsm;

namespace {
model::UPLVSM micro_uplvsm(uint64_t seed) {
  torch::manual_seed(seed);
  return model::require_uplvsm(model::make_model(test::micro_model()), "test");
}
}  // namespace

TEST(PoseMapperFile, AMapperTravelsApartFromItsModelAndComesBackTheSame) {
  auto net = micro_uplvsm(1);
  model::PoseMapper mapper(model::PoseMapperOptions{model::PoseMapperKind::Mlp, 8});
  {
    torch::NoGradGuard no_grad;
    for (auto& p : mapper->parameters()) p.normal_(0, 0.2);
  }
  const auto path = (test::temp_dir("mapper_file") / "m.safetensors").string();
  model::save_pose_mapper(path, *mapper, model::model_fingerprint(*net), {{"steps", 3}});
  const auto stored = io::read_pose_mapper_file(path);  // the format: kind and width by name, the tensors unprefixed
  EXPECT_EQ(stored.kind, "mlp");
  EXPECT_EQ(stored.hidden, 8);
  EXPECT_TRUE(torch::equal(stored.tensors.at("A"), mapper->A));
  auto file = model::load_pose_mapper(path);
  EXPECT_EQ(file.fit["steps"], 3);
  EXPECT_EQ(file.mapper->options.hidden, 8);
  EXPECT_FALSE(net->has_camera_control());
  model::attach_pose_mapper_file(*net, path);
  ASSERT_TRUE(net->has_camera_control());
  auto poses = torch::randn({1, 3, 7}), scene = torch::randn({1, model::kSceneConditioningDims});
  EXPECT_LT(test::max_abs_diff(net->pose_mapper(poses, scene), mapper(poses, scene)), 1e-6);
  // The model's own fingerprint ignores the mapper it now carries.
  EXPECT_EQ(model::model_fingerprint(*net), file.model_fingerprint);
}

TEST(PoseMapperFile, AMapperOfAnotherModelOrAFileThatIsNoMapperIsRefused) {
  auto net = micro_uplvsm(1), other = micro_uplvsm(2);
  const auto dir = test::temp_dir("mapper_file_errors");
  const auto path = (dir / "m.safetensors").string();
  model::PoseMapper mapper;
  model::save_pose_mapper(path, *mapper, model::model_fingerprint(*net), {});
  const auto error = test::error_of([&] { model::attach_pose_mapper_file(*other, path); });
  EXPECT_NE(error.find("fitted to another model"), std::string::npos) << error;
  EXPECT_FALSE(other->has_camera_control());

  const auto weights = (dir / "weights.safetensors").string();
  io::write_safetensors(weights, {{"pose_mapper.A", torch::eye(7)}});
  EXPECT_NE(test::error_of([&] { model::load_pose_mapper(weights); }).find("not a pose mapper file"),
            std::string::npos);
  // An MLP file whose tensors are missing is named, not half-loaded.
  const auto broken = (dir / "broken.safetensors").string();
  io::write_safetensors(
      broken, {{"pose_mapper.A", torch::eye(7)}, {"pose_mapper.b", torch::zeros({7})}},
      {{"format", io::kPoseMapperFormat}, {"kind", "mlp"}, {"hidden", "8"}, {"model_fingerprint", "0"}});
  const auto missing = test::error_of([&] { model::load_pose_mapper(broken); });
  EXPECT_NE(missing.find("mlp.0.weight"), std::string::npos) << missing;
}
