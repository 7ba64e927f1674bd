// `uplvsm info`: what this binary computes with (LibTorch, BLAS, threads, OpenMP policy, devices, MP4 output) and,
// given a config or checkpoint, the model's size.
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/config.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/mp4_writer.h"
#include "uplvsm/kernels/ops.h"
#include "uplvsm/model/model_factory.h"

namespace uplvsm::cli {

namespace {
void print_model_summary(const Config& c) {
  auto net = model::make_model(c.model);
  std::map<std::string, int64_t> by_module;
  for (const auto& item : net->named_parameters(true)) {
    auto key = item.key();
    auto top = key.substr(0, key.find('.'));
    by_module[top] += item.value().numel();
  }
  std::cout << fmt::format("model        {} ({}), {}x{} images, patch {}, {:.2f} M parameters\n", c.name,
                           to_string(c.model.variant), c.model.image_size, c.model.image_size, c.model.patch_size,
                           net->parameter_count() / 1e6);
  for (const auto& [name, n] : by_module) std::cout << fmt::format("  {:<38} {:>10.3f} M\n", name, n / 1e6);
}

// MP4 is optional at build time (UPLVSM_WITH_FFMPEG), and FFmpeg builds differ in which encoders they carry.
std::string mp4_output_description() {
  if (io::mp4_available()) return io::mp4_encoder_name();
#ifdef UPLVSM_WITH_FFMPEG
  return "off: this FFmpeg has no libx264 or mpeg4 encoder";
#else
  return "off: built without FFmpeg";
#endif
}
}  // namespace

void add_info_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("info",
                                 "Print the LibTorch version, BLAS in use, threads, devices; with --config or "
                                 "--checkpoint also the model's parameter counts, with --config the config in full "
                                 "(its 'extends' resolved, defaults filled in).");
  auto common = std::make_shared<CommonOptions>();
  auto config = std::make_shared<std::string>();
  auto checkpoint = std::make_shared<std::string>();
  add_common_options(cmd, *common);
  cmd->add_option("--config", *config, "a config JSON (configs/*.json)")->check(CLI::ExistingFile);
  cmd->add_option("--checkpoint", *checkpoint, "a uplvsm checkpoint (file, checkpoints dir or run dir)");
  cmd->callback([=] {
    apply_common_options(*common);
    std::cout << format_runtime_info(runtime_info());
    auto device = parse_device(common->device);
    std::cout << fmt::format("device       {}\n", device.str());
    std::cout << fmt::format("MP4 output   {}\n", mp4_output_description());
    std::cout << fmt::format("kernels      {}\n", kernels::describe_kernel_paths());
    if (!config->empty()) {
      const auto c = load_config(*config);
      print_model_summary(c);
      // Every key the run would use: the "extends" chain resolved and the defaults filled in.
      std::cout << "resolved config:\n" << config_to_json(c).dump(2) << "\n";
    }
    if (!checkpoint->empty()) {
      auto ckpt = io::read_checkpoint(*checkpoint);
      std::cout << fmt::format("checkpoint   {} (state {})\n", ckpt.path, ckpt.state.dump());
      print_model_summary(ckpt.config);
    }
  });
}

}  // namespace uplvsm::cli
