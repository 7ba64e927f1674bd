// `uplvsm export`: a training checkpoint (or a run's latest) -> the weights a user needs: model tensors + config,
// without the optimiser state (a third of the size), as shipped in models/.
#include <filesystem>
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/io/checkpoint_io.h"

namespace uplvsm::cli {

void add_export_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "export",
      "Write a weights-only checkpoint (model tensors + config + training step, no optimiser state) from a "
      "training checkpoint or a run directory's latest; it loads wherever --checkpoint is taken.");
  struct Args {
    std::string checkpoint, out;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("--checkpoint", a->checkpoint, "training checkpoint, run directory or checkpoints directory")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("--out", a->out, "weights file to write (.safetensors)")->required();
  cmd->callback([a] {
    const auto path = io::resolve_checkpoint(a->checkpoint);
    auto ck = io::read_checkpoint(path);
    auto state = ck.state;
    state["exported_from"] = std::filesystem::path(path).filename().string();
    state.erase("best");  // a training-run pointer, meaningless beside the exported file
    if (std::filesystem::path(a->out).has_parent_path())
      std::filesystem::create_directories(std::filesystem::path(a->out).parent_path());
    io::write_checkpoint(a->out, ck.config, state, ck.model, {});
    int64_t params = 0;
    for (const auto& [name, tensor] : ck.model) params += tensor.numel();
    std::cout << fmt::format(
        "wrote {} ({}, step {}, {} tensors, {} parameters, {:.1f} MB; {} optimiser tensors left out)\n", a->out,
        ck.config.name, state.value("step", 0), ck.model.size(), params, std::filesystem::file_size(a->out) / 1e6,
        ck.optimizer.size());
  });
}

}  // namespace uplvsm::cli
