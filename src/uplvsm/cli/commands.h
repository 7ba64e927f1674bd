// The subcommands of the `uplvsm` binary. Each add_* registers one subcommand (options + action) on the app.
#pragma once
#include <CLI/CLI.hpp>

#include <string>

namespace uplvsm::cli {

// Options every compute subcommand takes.
struct CommonOptions {
  std::string device = "auto";
  int threads = 0;  // 0: every core available
};
void add_common_options(CLI::App* cmd, CommonOptions& opt);
void apply_common_options(const CommonOptions& opt);

void add_info_command(CLI::App& app);
void add_make_dataset_command(CLI::App& app);
void add_train_command(CLI::App& app);
void add_eval_command(CLI::App& app);
void add_render_command(CLI::App& app);
void add_report_command(CLI::App& app);

}  // namespace uplvsm::cli
