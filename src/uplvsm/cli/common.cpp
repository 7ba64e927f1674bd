#include <spdlog/spdlog.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"

namespace uplvsm::cli {

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

}  // namespace uplvsm::cli
