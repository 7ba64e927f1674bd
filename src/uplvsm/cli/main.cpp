// uplvsm: novel views from two unposed photos (UP-LVSM), as one native binary. `uplvsm --help` lists subcommands.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <exception>
#include <iostream>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/io/image.h"

int main(int argc, char** argv) {
  uplvsm::ensure_passive_openmp(argv);
  CLI::App app{
      "uplvsm - UP-LVSM novel view synthesis from unposed images (ICLR 2026, 'The Less You Depend, The More You "
      "Learn'), native C++/LibTorch.\nTypical flow: make-dataset -> train -> eval -> render -> report; serve opens the "
      "viewer."};
  app.require_subcommand(1);
  // Global options, accepted before or after the subcommand's name.
  app.fallthrough();
  bool verbose = false;
  app.add_flag("--verbose", verbose, "on errors from LibTorch, also print its C++ backtrace");
  app.add_option_function<int64_t>(
         "--max-image-pixels", [](const int64_t& n) { uplvsm::io::set_max_image_pixels(n); },
         "refuse images whose header declares more pixels than this (decompression bombs); 0: no limit")
      ->default_val(uplvsm::io::kDefaultMaxImagePixels)
      ->check(CLI::NonNegativeNumber);
  uplvsm::cli::add_info_command(app);
  uplvsm::cli::add_make_dataset_command(app);
  uplvsm::cli::add_dataset_command(app);
  uplvsm::cli::add_train_command(app);
  uplvsm::cli::add_eval_command(app);
  uplvsm::cli::add_render_command(app);
  uplvsm::cli::add_serve_command(app);
  uplvsm::cli::add_report_command(app);
  uplvsm::cli::add_convert_command(app);
  uplvsm::cli::add_export_command(app);
  uplvsm::cli::add_study_command(app);
  uplvsm::cli::add_fit_mapper_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::cerr << "error: " << uplvsm::cli::error_message(e, verbose) << "\n";
    return 1;
  }
  return 0;
}
