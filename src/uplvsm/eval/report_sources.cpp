#include "uplvsm/eval/report_sources.h"

#include <algorithm>
#include <filesystem>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/core/json_input.h"
#include "uplvsm/core/runtime.h"

namespace uplvsm::eval {

namespace fs = std::filesystem;

ReportInputs report_inputs(const ModelDirs& d) {
  for (const auto* dir : {&d.run, &d.eval})
    if (!dir->empty() && !fs::is_directory(*dir)) throw std::runtime_error("report: no directory " + *dir);
  if (d.eval.empty()) throw std::runtime_error("report: an eval directory is required (eval=DIR / --eval DIR)");
  ReportInputs in;
  in.title = d.label;
  in.metrics_json = (fs::path(d.eval) / "metrics.json").string();
  if (!d.run.empty()) {
    in.config = read_json_file((fs::path(d.run) / "config.json").string(), "report:");
    in.train_log_jsonl = (fs::path(d.run) / "metrics.jsonl").string();
  }
  if (fs::is_directory(fs::path(d.eval) / "scenes"))
    for (const auto& e : fs::directory_iterator(fs::path(d.eval) / "scenes"))
      if (e.path().extension() == ".png") in.scene_grids.push_back(e.path().string());
  std::sort(in.scene_grids.begin(), in.scene_grids.end());
  for (const auto& dir : d.videos) {
    auto videos = read_json_file((fs::path(dir) / "videos.json").string(), "report:");
    if (videos.empty()) continue;
    const auto& v = videos[0];  // the first scene's video
    in.videos.push_back({v.value("trajectory", ""), v.value("mp4", ""), v.value("gif", ""), v.value("width", 0)});
  }
  in.runtime_info = format_runtime_info(runtime_info());
  return in;
}

ModelDirs parse_model_spec(const std::string& spec) {
  ModelDirs d;
  size_t start = 0;
  while (start <= spec.size()) {
    const size_t end = std::min(spec.find(',', start), spec.size());
    const auto item = spec.substr(start, end - start);
    const auto eq = item.find('=');
    const auto key = item.substr(0, eq), value = eq == std::string::npos ? "" : item.substr(eq + 1);
    if (eq == std::string::npos || value.empty())
      throw std::runtime_error(fmt::format("report --model '{}': '{}' is not KEY=VALUE", spec, item));
    if (key == "label")
      d.label = value;
    else if (key == "caption")
      d.caption = value;
    else if (key == "run")
      d.run = value;
    else if (key == "eval")
      d.eval = value;
    else if (key == "video")
      d.videos.push_back(value);
    else
      throw std::runtime_error(
          fmt::format("report --model '{}': unknown key '{}' (label, caption, run, eval, video)", spec, key));
    start = end + 1;
  }
  if (d.label.empty()) throw std::runtime_error(fmt::format("report --model '{}': label=NAME is required", spec));
  return d;
}

}  // namespace uplvsm::eval
