// `uplvsm convert`: the authors' UP-LVSM checkpoints and DINOv2 weight files -> our safetensors checkpoint (weights +
// config), with a per-module summary and an optional verification forward pass.
#include <chrono>
#include <filesystem>
#include <iostream>
#include <set>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/pretrained_weights.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/train/perceptual_loss.h"

namespace uplvsm::cli {

namespace fs = std::filesystem;

namespace {

struct ConvertArgs {
  CommonOptions common;
  std::string input, output, config;
  bool verify = false;
};

void print_summary(const model::NovelViewModelImpl& net, const io::PretrainedWeights& w) {
  std::map<std::string, int64_t> per_module;
  for (const auto& item : net.named_parameters(true)) {
    const auto& key = item.key();
    auto dot = key.find('.');
    per_module[dot == std::string::npos ? key : key.substr(0, dot)] += item.value().numel();
  }
  std::set<std::string> dtypes;
  for (const auto& [k, v] : w.tensors) dtypes.insert(std::string(c10::toString(v.scalar_type())));
  std::cout << fmt::format("read {} ({}{}): {} tensors, {} weights, dtype {}\n", w.path, w.container,
                           w.found_at.empty() ? "" : ", under '" + w.found_at + "'", w.tensors.size(),
                           io::to_string(w.source), fmt::join(dtypes, "/"));
  for (const auto& [name, count] : per_module) std::cout << fmt::format("  {:<40} {:>14} parameters\n", name, count);
  std::cout << fmt::format("  {:<40} {:>14} parameters\n", "total", net.parameter_count());
}

// The known extras of official checkpoints: the perceptual loss's VGG19 (MatConvNet ImageNet weights). Its conv
// layers are saved under torchvision's `features.N` names, the format the perceptual loss reads; the untrained
// classifier and the aliased `blocks.*` keys are left out.
void write_vgg19_extras(const io::PretrainedWeights& w, const std::string& output) {
  io::TensorMap vgg;
  const std::string prefix = "loss_computer.perceptual_loss_module.vgg.";
  for (const auto& [k, v] : w.tensors)
    if (k.rfind(prefix + "features.", 0) == 0) vgg[k.substr(prefix.size())] = v.contiguous();
  if (vgg.empty()) return;
  auto path = fs::path(output).replace_extension(".vgg19.safetensors").string();
  // Marked, so the perceptual loss prepares MatConvNet's input for them (train/perceptual_loss.h).
  io::write_safetensors(path, vgg,
                        {{"source", w.path},
                         {"content", "VGG19 features of the perceptual loss"},
                         {train::kVggInputMetadataKey, train::to_string(train::VggInput::MatConvNet)}});
  std::cout << fmt::format("wrote the {} VGG19 feature tensors of the perceptual loss to {}\n", vgg.size(), path);
}

// Reloads the written file and checks every tensor and one forward pass.
void verify(const std::string& output, const model::NovelViewModelImpl& converted, const torch::Device& device) {
  Config config;
  auto net = model::load_model(output, device, &config);
  auto expected = io::state_dict(converted);
  for (const auto& [k, v] : io::state_dict(*net))
    if (!torch::equal(v, expected.at(k)))
      throw std::runtime_error("verify: tensor " + k + " changed in the round trip");
  torch::NoGradGuard no_grad;
  torch::manual_seed(0);
  const int64_t s = config.model.image_size;
  auto images = torch::rand({1, 3, 3, s, s}, torch::TensorOptions().device(device));
  auto K = torch::tensor({0.9 * s, 0.9 * s, 0.5 * s, 0.5 * s}, torch::TensorOptions().device(device)).expand({1, 3, 4});
  auto t0 = std::chrono::steady_clock::now();
  // Posed models need cameras: a camera 1 unit to the right per view.
  auto c2w = torch::eye(4, images.options()).repeat({1, 3, 1, 1});
  c2w.select(1, 1)[0][0][3] = 1.0;
  c2w.select(1, 2)[0][0][3] = 0.5;
  model::Views inputs{images.narrow(1, 0, 2), K.narrow(1, 0, 2), c2w.narrow(1, 0, 2)};
  model::Views targets{images.narrow(1, 2, 1), K.narrow(1, 2, 1), c2w.narrow(1, 2, 1)};
  auto out = net->render(inputs, targets, net->default_target_poses());
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  auto pose = out.pose_enc.defined() ? out.pose_enc.cpu().contiguous() : torch::zeros({7});
  if (!torch::isfinite(out.render).all().item<bool>() || !torch::isfinite(pose).all().item<bool>())
    throw std::runtime_error("verify: the forward pass produced NaN/Inf");
  std::vector<float> pose7(pose.data_ptr<float>(), pose.data_ptr<float>() + 7);
  std::cout << fmt::format(
      "verify: {} tensors identical after reload; forward 2 inputs + 1 target at {}x{} px in "
      "{:.2f} s, render mean {:.4f}, pose {:.4f}\n",
      expected.size(), s, s, seconds, out.render.mean().item<double>(), fmt::join(pose7, " "));
}

void run_convert(const ConvertArgs& a) {
  apply_common_options(a.common);
  auto w = io::read_pretrained_weights(a.input);
  Config config;
  if (!a.config.empty()) config = load_config(a.config);
  nlohmann::json state = {{"step", 0}, {"converted_from", a.input}, {"source", io::to_string(w.source)}};
  model::NovelViewModel net{nullptr};
  if (w.source == io::WeightSource::Uplvsm) {
    if (a.config.empty()) {
      config.name = fs::path(a.input).stem().string();
      config.model = model::infer_model_config(w.tensors, config.model);
    }
    validate_config(config, a.config.empty() ? a.input + " (inferred config)" : a.config);
    net = model::make_model(config.model);
    auto report = io::load_state_dict(*net, w.tensors, a.input);
    std::cout << report.summary(a.input) << "\n";
  } else {
    if (a.config.empty())
      throw std::runtime_error(
          fmt::format("convert: {} holds {} weights; give --config (e.g. configs/paper_x224.json) "
                      "for the UP-LVSM model to initialise around them",
                      a.input, io::to_string(w.source)));
    validate_config(config, a.config);
    torch::manual_seed(static_cast<uint64_t>(config.training.seed));
    net = model::make_model(config.model);
    auto report = model::load_dinov2_into_tokenizer(*net, w.tensors, a.input);
    std::cout << report.summary(a.input) << "\n(the rest of the model is freshly initialised with seed "
              << config.training.seed << ")\n";
  }
  print_summary(*net, w);
  io::write_checkpoint(a.output, config, state, io::state_dict(*net), {});
  std::cout << fmt::format("wrote {} ({})\n", a.output, config.name);
  write_vgg19_extras(w, a.output);
  if (a.verify) verify(a.output, *net, parse_device(a.common.device));
}

}  // namespace

void add_convert_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "convert",
      "Convert weights to a uplvsm checkpoint (safetensors + config): the authors' UP-LVSM checkpoint "
      "(.pt training checkpoint or .safetensors; dimensions inferred unless --config), or DINOv2 weights "
      "(Meta .pth or HuggingFace safetensors; needs --config) placed in a freshly initialised UP-LVSM.");
  auto a = std::make_shared<ConvertArgs>();
  add_common_options(cmd, a->common);
  cmd->add_option("--input", a->input, "weights file: .pt / .pth / .safetensors")->required()->check(CLI::ExistingFile);
  cmd->add_option("--output", a->output, "checkpoint to write (.safetensors)")->required();
  cmd->add_option("--config", a->config, "config JSON (required for DINOv2 inputs; optional for UP-LVSM ones)")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--verify", a->verify, "reload the output and run one forward pass");
  cmd->callback([a] { run_convert(*a); });
}

}  // namespace uplvsm::cli
