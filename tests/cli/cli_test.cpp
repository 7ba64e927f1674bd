#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "test_util.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/state_dict.h"
#include "uplvsm/train/perceptual_loss.h"

namespace {
struct Run {
  int status;
  std::string output;
};

Run run(const std::string& args, const std::string& env_prefix = "") {
  std::string cmd = env_prefix + std::string(UPLVSM_CLI) + " " + args + " 2>&1";
  Run r{0, ""};
  FILE* pipe = popen(cmd.c_str(), "r");
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof(buf), pipe)) > 0) r.output.append(buf, n);
  r.status = pclose(pipe);
  return r;
}
}  // namespace

TEST(Cli, HelpListsEverySubcommand) {
  auto r = run("--help");
  EXPECT_EQ(r.status, 0) << r.output;
  for (std::string sub : {"info", "make-dataset", "train", "eval", "render", "report", "convert"})
    EXPECT_NE(r.output.find(sub), std::string::npos) << sub;
  for (std::string sub : {"info", "make-dataset", "train", "eval", "render", "report", "convert"}) {
    auto h = run(sub + " --help");
    EXPECT_EQ(h.status, 0) << sub << ": " << h.output;
    EXPECT_NE(h.output.find("--"), std::string::npos) << sub;
  }
}

TEST(Cli, InfoReportsOpenBlas) {
  // Started with no wait policy in the environment, the binary re-executes itself with a passive one.
  auto r = run("info --config " + std::string(UPLVSM_SOURCE_DIR) + "/configs/tiny.json",
               "env -u OMP_WAIT_POLICY -u UPLVSM_NO_REEXEC ");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("OpenMP wait  PASSIVE"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("M parameters"), std::string::npos) << r.output;
  // The checks above still count: a skip after a failure leaves the test failed.
  if (const auto why = uplvsm::test::no_shared_blas()) GTEST_SKIP() << *why;
  EXPECT_NE(r.output.find("OpenBLAS"), std::string::npos) << r.output;  // not the reference BLAS
}

TEST(Cli, BadArgumentsAndFilesGiveClearErrors) {
  auto missing = run("train --config /nonexistent/tiny.json --data /tmp --run /tmp/x");
  EXPECT_NE(missing.status, 0);
  EXPECT_NE(missing.output.find("/nonexistent/tiny.json"), std::string::npos) << missing.output;

  auto no_ckpt = run("eval --checkpoint /nonexistent/run --data /tmp --out /tmp/e");
  EXPECT_NE(no_ckpt.status, 0);
  EXPECT_NE(no_ckpt.output.find("/nonexistent/run"), std::string::npos) << no_ckpt.output;

  auto device = run("info --device tpu");
  EXPECT_NE(device.status, 0);
  EXPECT_NE(device.output.find("tpu"), std::string::npos) << device.output;

  auto unknown = run("fly");
  EXPECT_NE(unknown.status, 0);

  // The enum choices are checked where they are given, naming the value and the choices.
  const std::string tiny = std::string(UPLVSM_SOURCE_DIR) + "/configs/tiny.json";
  auto amp = run("eval --checkpoint /nonexistent/run --data /tmp --out /tmp/e --amp fp16");
  EXPECT_NE(amp.status, 0);
  EXPECT_NE(amp.output.find("--amp: fp16 not in {none,bf16}"), std::string::npos) << amp.output;
  auto poses = run("train --config " + tiny + " --data /tmp --run /tmp/x --set training.target_poses=sfm");
  EXPECT_NE(poses.status, 0);
  EXPECT_NE(poses.output.find("training.target_poses must be 'auto', 'estimator', 'mapper' or 'dataset', got 'sfm'"),
            std::string::npos)
      << poses.output;
  // The tokenizer stage starts from scratch; --init belongs to the stage that reads its output.
  auto stage = run("train --stage tokenizer --config " + tiny + " --data /tmp --run /tmp/x --init " + tiny);
  EXPECT_NE(stage.status, 0);
  EXPECT_NE(stage.output.find("--stage tokenizer starts the tokenizer from scratch"), std::string::npos)
      << stage.output;
}

TEST(Cli, ConvertOfficialCheckpointAndVerify) {
  UPLVSM_NEEDS_FIXTURES();
  auto dir = uplvsm::test::temp_dir("cli_convert");
  auto out = (dir / "official.safetensors").string();
  auto r = run("convert --input " + uplvsm::test::fixture("official_uplvsm/checkpoint.pt") + " --output " + out +
               " --verify");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("torch zip, under 'model'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("667047 parameters"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("verify: 93 tensors identical after reload"), std::string::npos) << r.output;
  auto info = run("info --checkpoint " + out);
  EXPECT_EQ(info.status, 0) << info.output;

  auto dino = run("convert --input " + uplvsm::test::fixture("dinov2/weights.pth") + " --output " + out);
  EXPECT_NE(dino.status, 0);
  EXPECT_NE(dino.output.find("give --config"), std::string::npos) << dino.output;
}

// An official checkpoint trained with the perceptual loss carries its MatConvNet VGG19: convert writes it beside the
// model, marked, so `train --vgg19` prepares the loss's input for those weights without being told.
TEST(Cli, ConvertMarksTheOfficialVgg19AsMatConvNetInput) {
  UPLVSM_NEEDS_FIXTURES();
  using namespace uplvsm;
  auto dir = test::temp_dir("cli_convert_vgg");
  auto tensors = io::read_safetensors(test::fixture("official_uplvsm/model.safetensors")).tensors;
  for (const auto& [k, v] : io::state_dict(*train::PerceptualLoss()->vgg))
    tensors["loss_computer.perceptual_loss_module.vgg." + k] = v;
  const auto input = (dir / "with_vgg.safetensors").string(), out = (dir / "converted.safetensors").string();
  io::write_safetensors(input, tensors);
  auto r = run("convert --input " + input + " --output " + out);
  ASSERT_EQ(r.status, 0) << r.output;
  const auto vgg = (dir / "converted.vgg19.safetensors").string();
  EXPECT_EQ(io::read_safetensors(vgg).metadata.at(train::kVggInputMetadataKey), "matconvnet");
  EXPECT_EQ(train::load_perceptual_loss(vgg)->input, train::VggInput::MatConvNet);
  test::remove_tree(dir);
}
