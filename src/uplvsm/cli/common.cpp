#include <vector>

#include <spdlog/spdlog.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/kernels/ops.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/pose_mapper_file.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::cli {

std::string error_message(const std::exception& e, bool verbose) {
  if (verbose) return e.what();
  if (const auto* c10 = dynamic_cast<const c10::Error*>(&e)) return c10->what_without_backtrace();
  // A LibTorch message wrapped into another error keeps its backtrace: cut it at the line that starts it.
  std::string message = e.what();
  const auto at = message.find("\nException raised from ");
  if (at != std::string::npos) message.erase(at);
  return message;
}

void add_common_options(CLI::App* cmd, CommonOptions& opt) {
  cmd->add_option("--device", opt.device, "cpu, cuda, cuda:N or auto (cuda when available)")->capture_default_str();
  cmd->add_option("--threads", opt.threads, "intra-op threads (0: every core this process may use)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
}

void apply_common_options(const CommonOptions& opt) {
  init_runtime(opt.threads);
  spdlog::set_pattern("[%H:%M:%S] %^%l%$ %v");
}

void log_kernel_paths() { spdlog::info("kernels: {}", kernels::describe_kernel_paths()); }

void add_model_options(CLI::App* cmd, ModelSource& src) {
  cmd->add_option("--checkpoint", src.checkpoint,
                  "model weights: a uplvsm checkpoint (file, checkpoints dir or run dir) or the authors' UP-LVSM .pt / "
                  ".safetensors")
      ->required();
  cmd->add_option("--config", src.config,
                  "config JSON for an official checkpoint (image size, dimensions); default: inferred from the "
                  "weights at 224 px. Ignored for uplvsm checkpoints, which carry their config")
      ->check(CLI::ExistingFile);
}

void add_mapper_option(CLI::App* cmd, ModelSource& src) {
  cmd->add_option("--mapper", src.mapper,
                  "a pose mapper fitted to this checkpoint by `uplvsm fit-mapper` (camera control for a model "
                  "without one, the authors' included); replaces a mapper the checkpoint has")
      ->check(CLI::ExistingFile);
}

model::NovelViewModel load_model_from_source(const ModelSource& src, torch::Device device, Config* config_out) {
  auto net = model::load_model_with_config_file(src.checkpoint, src.config, device, config_out);
  if (!src.mapper.empty()) {
    model::attach_pose_mapper_file(*model::require_uplvsm(net, "--mapper (camera control through latent poses)"),
                                   src.mapper);
    if (config_out) config_out->model.pose_mapper = true;
  }
  return net;
}

CLI::Option* add_amp_option(CLI::App* cmd, Amp& amp, const std::string& help) {
  return cmd
      ->add_option_function<std::string>(
          "--amp", [&amp](const std::string& name) { amp = parse_amp(name); }, help)
      ->check(CLI::IsMember({to_string(Amp::None), to_string(Amp::Bf16)}))
      ->default_str(to_string(amp));
}

CLI::Option* add_vgg19_input_option(CLI::App* cmd, train::VggInput& input) {
  return cmd
      ->add_option_function<std::string>(
          "--vgg19-input", [&input](const std::string& name) { input = train::parse_vgg_input(name); },
          "the input the --vgg19 weights expect: matconvnet (the official checkpoint's, 255 x image - mean) or "
          "torchvision (torchvision's vgg19(), [0, 1] normalised by the ImageNet mean and std); auto: the file's "
          "marker (`uplvsm convert` marks the files it writes), an error without one")
      ->check(CLI::IsMember({"auto", "matconvnet", "torchvision"}))
      ->default_str(train::to_string(input));
}

CLI::Option* add_target_poses_option(CLI::App* cmd, TargetPoses& choice, const std::string& help) {
  std::vector<std::string> names;
  for (auto c : {TargetPoses::Auto, TargetPoses::Estimator, TargetPoses::Mapper, TargetPoses::Dataset})
    names.push_back(to_string(c));
  return cmd
      ->add_option_function<std::string>(
          "--target-poses", [&choice](const std::string& name) { choice = parse_target_poses(name); }, help)
      ->check(CLI::IsMember(names))
      ->default_str(to_string(choice));
}

void add_scene_source_options(CLI::App* cmd, SceneSource& src, const std::string& data_help,
                              const std::string& index_help) {
  cmd->add_option("--data", src.data, data_help)->check(CLI::ExistingDirectory);
  cmd->add_option("--split", src.split, "dataset split")->capture_default_str();
  cmd->add_option("--index", src.index, index_help);
}

}  // namespace uplvsm::cli
