// `uplvsm report`: one HTML page tying a run together — headline metrics vs baselines, training curve, videos,
// image grids, config and machine facts; or, with --model given several times, models side by side.
#include <filesystem>
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/json_input.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/eval/comparison_report.h"
#include "uplvsm/eval/report.h"
#include "uplvsm/eval/report_sources.h"

namespace uplvsm::cli {

namespace fs = std::filesystem;

namespace {

void print_headline(const std::string& label, const std::string& metrics_json) {
  const auto metrics = read_json_file(metrics_json, "report:");
  const auto& t = metrics.at("table");
  std::cout << fmt::format(
      "  {}: held-out PSNR {:.2f} dB | copy nearest {:.2f} dB | mean colour {:.2f} dB ({} "
      "scenes)\n",
      label, t.at("model").at("psnr").get<double>(), t.at("copy_nearest").at("psnr").get<double>(),
      t.at("mean_colour").at("psnr").get<double>(), metrics.value("scenes", 0));
}

}  // namespace

void add_report_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("report",
                                 "Write an HTML report (index.html) from a training run, an eval output and "
                                 "render outputs; or several models side by side (--model, repeated).");
  struct Args {
    eval::ModelDirs single;
    std::vector<std::string> models;
    std::string out, title = "UP-LVSM report";
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("--run", a->single.run, "training run directory (config.json, metrics.jsonl)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--eval", a->single.eval, "directory written by `uplvsm eval`")->check(CLI::ExistingDirectory);
  cmd->add_option("--video", a->single.videos, "directories written by `uplvsm render` (one or more)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--model", a->models,
                  "a model of a side-by-side page: 'label=NAME,eval=DIR[,run=DIR][,video=DIR...][,caption=TEXT]' "
                  "(repeat for each column; replaces --run/--eval/--video)");
  cmd->add_option("--title", a->title, "page title")->capture_default_str();
  cmd->add_option("--out", a->out, "report directory")->required();
  cmd->callback([a] {
    if (a->models.empty()) {
      a->single.label = a->title;
      auto page = eval::write_report(a->out, eval::report_inputs(a->single));
      std::cout << fmt::format("report: {}\n", fs::absolute(page).string());
      print_headline("UP-LVSM", (fs::path(a->single.eval) / "metrics.json").string());
      return;
    }
    if (!a->single.eval.empty() || !a->single.run.empty() || !a->single.videos.empty())
      throw std::runtime_error("report: give either --model (repeated) or --run/--eval/--video, not both");
    std::vector<eval::ComparedModel> models;
    std::vector<eval::ModelDirs> dirs;
    for (const auto& spec : a->models) {
      dirs.push_back(eval::parse_model_spec(spec));
      models.push_back({dirs.back().label, dirs.back().caption, eval::report_inputs(dirs.back())});
    }
    auto page = eval::write_comparison_report(a->out, a->title, models, format_runtime_info(runtime_info()));
    std::cout << fmt::format("report: {}\n", fs::absolute(page).string());
    for (const auto& d : dirs) print_headline(d.label, (fs::path(d.eval) / "metrics.json").string());
  });
}

}  // namespace uplvsm::cli
