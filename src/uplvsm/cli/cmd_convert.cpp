// `uplvsm convert`: the authors' UP-LVSM checkpoints and DINOv2 weight files -> our safetensors checkpoint (weights +
// config), with a per-module summary and an optional verification forward pass.
#include <iostream>
#include <set>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/io/pretrained_weights.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/round_trip_check.h"
#include "uplvsm/model/weight_conversion.h"
#include "uplvsm/train/vgg19_extraction.h"

namespace uplvsm::cli {

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
  const auto w = io::read_pretrained_weights(a.input);
  const auto c = model::convert_weights(w, a.input, a.config);
  std::cout << c.load_summary << "\n";
  if (c.tokenizer_only)
    std::cout << "(the rest of the model is freshly initialised with seed " << c.config.training.seed << ")\n";
  print_summary(*c.net, w);
  model::write_converted(a.output, a.input, w, c);
  std::cout << fmt::format("wrote {} ({})\n", a.output, c.config.name);
  // The known extras of official checkpoints: the perceptual loss's VGG19, for a later `train --vgg19`.
  if (const auto vgg = train::write_vgg19_extras(w, a.output); vgg.tensors > 0)
    std::cout << fmt::format("wrote the {} VGG19 feature tensors of the perceptual loss to {}\n", vgg.tensors,
                             vgg.path);
  if (a.verify) verify(a.output, *c.net, parse_device(a.common.device));
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
