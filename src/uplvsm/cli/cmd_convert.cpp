// `uplvsm convert`: the authors' UP-LVSM checkpoints and DINOv2 weight files -> our safetensors checkpoint (weights +
// config), with a per-module summary and an optional verification forward pass.
#include <filesystem>
#include <iostream>
#include <set>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/pretrained_weights.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/round_trip_check.h"
#include "uplvsm/train/vgg19_extraction.h"

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

// Reloads the written file and checks every tensor and one forward pass.
void verify(const std::string& output, const model::NovelViewModelImpl& converted, const torch::Device& device) {
  const auto r = model::check_round_trip(output, converted, device);
  std::cout << fmt::format(
      "verify: {} tensors identical after reload; forward 2 inputs + 1 target at {}x{} px in "
      "{:.2f} s, render mean {:.4f}, pose {:.4f}\n",
      r.tensors, r.image_size, r.image_size, r.seconds, r.render_mean, fmt::join(r.pose, " "));
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
  // The known extras of official checkpoints: the perceptual loss's VGG19, for a later `train --vgg19`.
  if (const auto vgg = train::write_vgg19_extras(w, a.output); vgg.tensors > 0)
    std::cout << fmt::format("wrote the {} VGG19 feature tensors of the perceptual loss to {}\n", vgg.tensors,
                             vgg.path);
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
