// The subcommands of the `uplvsm` binary. Each add_* registers one subcommand (options + action) on the app.
#pragma once
#include <torch/torch.h>
#include <CLI/CLI.hpp>

#include <functional>
#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/train/perceptual_loss.h"

namespace uplvsm::cli {

// Options every compute subcommand takes.
struct CommonOptions {
  std::string device = "auto";
  int threads = 0;  // 0: every core available
};
void add_common_options(CLI::App* cmd, CommonOptions& opt);
void apply_common_options(const CommonOptions& opt);
// Logs which path each kernel takes on this CPU (kernels::describe_kernel_paths).
void log_kernel_paths();

// --checkpoint (ours or the authors') and --config, which official files need only when their dimensions cannot be
// inferred as wanted (e.g. to run at 518 px: configs/paper_x518.json).
struct ModelSource {
  std::string checkpoint, config;
  std::string mapper;  // --mapper: a pose mapper file fitted to the checkpoint (fit-mapper); empty: none
};
void add_model_options(CLI::App* cmd, ModelSource& src);
// --mapper FILE, for the commands that render real cameras (eval, render, serve).
void add_mapper_option(CLI::App* cmd, ModelSource& src);
// The model of `src` on `device` (model::load_model_with_config_file), with --mapper's pose mapper attached.
model::NovelViewModel load_model_from_source(const ModelSource& src, torch::Device device, Config* config_out);

// --amp (none: fp32, bf16: autocast) and --target-poses (auto, estimator, mapper, dataset), parsed into their enums
// here, once; `help` says what the choice applies to in this command.
CLI::Option* add_amp_option(CLI::App* cmd, Amp& amp, const std::string& help);
CLI::Option* add_target_poses_option(CLI::App* cmd, TargetPoses& choice, const std::string& help);
// --vgg19-input (auto, matconvnet, torchvision): the input the --vgg19 weights expect (train/perceptual_loss.h).
CLI::Option* add_vgg19_input_option(CLI::App* cmd, train::VggInput& input);

// The scenes eval, render and serve read: a dataset root, its split and an evaluation index (default
// <data>/evaluation_index.json).
struct SceneSource {
  std::string data, split = "test", index;
};
void add_scene_source_options(CLI::App* cmd, SceneSource& src, const std::string& data_help,
                              const std::string& index_help);

// What the CLI prints for an uncaught error: its message, without LibTorch's C++ backtrace ("Exception raised
// from ... frame #0 ...") unless `verbose`, also when another error's message embeds a LibTorch one.
std::string error_message(const std::exception& e, bool verbose);

void add_info_command(CLI::App& app);
void add_make_dataset_command(CLI::App& app);
void add_dataset_command(CLI::App& app);
// dataset import: bring-your-own photo folders (cmd_dataset_import.cpp), registered under `dataset`.
void add_dataset_import_command(CLI::App& dataset);
void add_train_command(CLI::App& app);
void add_eval_command(CLI::App& app);
void add_render_command(CLI::App& app);
void add_serve_command(CLI::App& app);
void add_report_command(CLI::App& app);
void add_convert_command(CLI::App& app);
void add_export_command(CLI::App& app);
void add_study_command(CLI::App& app);
void add_fit_mapper_command(CLI::App& app);
// study mapper-scenes (cmd_fit_mapper.cpp), registered under `study`.
void add_mapper_scenes_command(CLI::App& study);
// study camera-paths (cmd_camera_paths.cpp), registered under `study`.
void add_camera_paths_command(CLI::App& study);
// study scaling / study pose-noise (cmd_study_grid.cpp), registered under `study`.
void add_study_grid_commands(CLI::App& study);

}  // namespace uplvsm::cli
