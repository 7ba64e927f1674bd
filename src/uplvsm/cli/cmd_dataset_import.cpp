// `uplvsm dataset import`: bring your own scene. A photo folder (with a COLMAP text model or a nerfstudio
// transforms.json when poses are known) becomes one pixelSplat chunk ROOT/SPLIT/<scene>.torch, merged into the
// split's index.json, optionally into ROOT/evaluation_index.json (the file `eval` and `render` read by default),
// and, for photos without poses, listed in ROOT/SPLIT/unposed.json so tools needing real poses can refuse it.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/json_input.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/data/scene_import.h"
#include "uplvsm/io/atomic_file.h"

namespace uplvsm::cli {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct ImportArgs {
  data::SceneImportOptions import;
  std::string out, split = "test";
  std::vector<int64_t> context, target;
  bool force = false;
};

void write_json(const fs::path& path, const json& j) {
  const std::string text = j.dump(2) + "\n";
  io::write_file_atomic(path.string(), text.data(), text.size());
}

void check_frames(const ImportArgs& a, int64_t n) {
  for (const auto* list : {&a.context, &a.target})
    for (int64_t f : *list)
      if (f < 0 || f >= n)
        throw std::runtime_error(
            fmt::format("dataset import: frame {} of --{} is out of range: the scene has {} "
                        "frames (0..{})",
                        f, list == &a.context ? "context" : "target", n, n - 1));
}

// The files an import changes, read and checked before any of them is written.
struct ImportPlan {
  fs::path split_dir, chunk_path, eval_path, unposed_path;
  std::string chunk_name;
  std::map<std::string, std::string> index;  // the split's index.json
  json eval_index = json::object();          // ROOT/evaluation_index.json as raw JSON
  std::string stale_eval;  // an existing evaluation entry that a --force re-import leaves pointing past the end
  std::set<std::string> unposed;
};

// The split's index and chunk file: refuse to overwrite another scene's chunk, or this scene's without --force.
void plan_chunk(const ImportArgs& a, const std::string& key, ImportPlan& plan) {
  const std::string& chunk_name = plan.chunk_name;
  const fs::path& chunk_path = plan.chunk_path;
  if (fs::is_directory(plan.split_dir)) plan.index = data::read_chunk_index(plan.split_dir.string());
  std::vector<std::string> sharing;  // other scenes stored in the file we would overwrite
  for (const auto& [k, file] : plan.index)
    if (file == chunk_name && k != key) sharing.push_back(k);
  if (!sharing.empty())
    throw std::runtime_error(fmt::format("dataset import: {} holds other scenes ({}); choose another --scene",
                                         chunk_path.string(), fmt::join(sharing, ", ")));
  if (!a.force && plan.index.count(key))
    throw std::runtime_error(
        fmt::format("dataset import: scene '{}' is already in {} ({}); pass --force to replace "
                    "it or --scene to choose another name",
                    key, (plan.split_dir / "index.json").string(), plan.index[key]));
  if (!a.force && fs::exists(chunk_path))
    throw std::runtime_error(fmt::format("dataset import: {} exists; pass --force to replace it", chunk_path.string()));
}

void plan_eval_index(const ImportArgs& a, const std::string& key, int64_t n, ImportPlan& plan) {
  const fs::path& eval_path = plan.eval_path;
  if (!fs::exists(eval_path)) return;
  // Merged as raw JSON: read_eval_index (used here to validate, naming the file and key) drops null entries and
  // unknown fields, which must survive the merge.
  const auto entries = data::read_eval_index(eval_path.string());
  plan.eval_index = read_json_file(eval_path.string(), "dataset import:");
  if (!a.context.empty() && !a.force && plan.eval_index.contains(key))
    throw std::runtime_error(fmt::format("dataset import: scene '{}' is already in {}; pass --force to replace it", key,
                                         eval_path.string()));
  for (const auto& e : entries)
    if (a.context.empty() && e.key == key)
      for (const auto* list : {&e.context, &e.target})
        if (std::any_of(list->begin(), list->end(), [&](int64_t f) { return f >= n; }))
          plan.stale_eval = fmt::format(
              "{} keeps its entry for '{}', which names frames beyond this scene's {}: "
              "give --context/--target to replace it",
              eval_path.string(), key, n);
}

// Check every file we are about to change before writing any of them.
ImportPlan plan_import(const ImportArgs& a, const std::string& key, int64_t n) {
  ImportPlan plan;
  const fs::path root(a.out);
  plan.split_dir = root / a.split;
  plan.chunk_name = key + ".torch";
  plan.chunk_path = plan.split_dir / plan.chunk_name;
  plan_chunk(a, key, plan);
  plan.eval_path = root / "evaluation_index.json";
  plan_eval_index(a, key, n, plan);
  plan.unposed_path = plan.split_dir / "unposed.json";
  const auto unposed_list = data::read_unposed_keys(plan.split_dir.string());
  plan.unposed.insert(unposed_list.begin(), unposed_list.end());
  return plan;
}

// The chunk, the split's index, unposed.json (only when it changes) and the evaluation entry.
void write_import(const ImportArgs& a, const data::ImportedScene& result, ImportPlan& plan) {
  const std::string& key = result.scene.key;
  fs::create_directories(plan.split_dir);
  data::write_chunk(plan.chunk_path.string(), {result.scene});  // atomic
  plan.index[key] = plan.chunk_name;
  data::write_chunk_index(plan.split_dir.string(), plan.index);
  auto& unposed = plan.unposed;
  const bool was_unposed = unposed.count(key) > 0;
  if (!result.poses_known)
    unposed.insert(key);
  else
    unposed.erase(key);
  if (!result.poses_known || was_unposed)
    write_json(plan.unposed_path, json(std::vector<std::string>(unposed.begin(), unposed.end())));
  if (!a.context.empty()) {
    plan.eval_index[key] = {{"context", a.context}, {"target", a.target}};
    write_json(plan.eval_path, plan.eval_index);
  }
}

void print_import_summary(const ImportArgs& a, const data::ImportedScene& result, const ImportPlan& plan) {
  const std::string& key = result.scene.key;
  const int64_t n = result.scene.cameras.size(0);
  for (const auto& w : result.warnings) std::cout << "warning: " << w << "\n";
  if (!plan.stale_eval.empty()) std::cout << "warning: " << plan.stale_eval << "\n";
  if (!a.context.empty() && !result.poses_known)
    std::cout << fmt::format(
        "note: '{}' has no poses: the unposed UP-LVSM can be evaluated on it (it estimates "
        "target poses from the target images), the posed variants and --target-poses "
        "dataset/mapper cannot\n",
        key);
  std::cout << fmt::format(
      "imported '{}': {} frames{}, intrinsics {}, poses {}, {} warning(s){} -> {}{}\n", key, n,
      result.turned_upright ? fmt::format(" ({} turned upright by their EXIF orientation)", result.turned_upright) : "",
      result.intrinsics_source, result.poses_known ? "known" : "unknown (listed in unposed.json)",
      result.warnings.size(), result.skipped ? fmt::format(", {} image(s) skipped", result.skipped) : "",
      plan.chunk_path.string(), a.context.empty() ? "" : " + evaluation_index.json");
}

void run_import(const ImportArgs& a) {
  if ((a.context.empty()) != (a.target.empty()))
    throw std::runtime_error("dataset import: --context and --target go together");
  const auto result = data::import_scene(a.import);
  const int64_t n = result.scene.cameras.size(0);
  check_frames(a, n);
  auto plan = plan_import(a, result.scene.key, n);
  write_import(a, result, plan);
  print_import_summary(a, result, plan);
}

}  // namespace

void add_dataset_import_command(CLI::App& dataset) {
  auto* cmd = dataset.add_subcommand(
      "import",
      "Import your own scene: a folder of photos (JPEG/PNG), with a COLMAP text model (--colmap: cameras.txt, "
      "images.txt) or a nerfstudio transforms.json (--transforms) when the poses are known, into ROOT/SPLIT/"
      "<scene>.torch + index.json. Intrinsics: from the model, else each JPEG's EXIF focal length (a 35 mm "
      "equivalent of 8 to 3000 mm, by the diagonal; others are reported and not used), else a --fov horizontal field "
      "of view. Photos without a model are turned upright by their EXIF orientation. Photos alone get identity "
      "poses and are listed in ROOT/SPLIT/unposed.json (usable "
      "for unposed training, evaluation of the unposed model and rendering). --context/--target add the scene to "
      "ROOT/evaluation_index.json.");
  auto a = std::make_shared<ImportArgs>();
  cmd->add_option("--images", a->import.images_dir, "folder of the photos (*.jpg, *.jpeg, *.png)")
      ->required()
      ->check(CLI::ExistingDirectory);
  auto* colmap = cmd->add_option("--colmap", a->import.colmap_dir,
                                 "COLMAP text model folder holding cameras.txt and images.txt (e.g. sparse/0)")
                     ->check(CLI::ExistingDirectory);
  auto* transforms = cmd->add_option("--transforms", a->import.transforms_path,
                                     "nerfstudio / instant-NGP transforms.json (file paths relative to its folder)")
                         ->check(CLI::ExistingFile);
  colmap->excludes(transforms);
  cmd->add_option("--fov", a->import.fov_deg,
                  "horizontal field of view (degrees) for photos with neither a model camera nor an EXIF focal length")
      ->check(CLI::Range(1.0, 179.0))
      ->capture_default_str();
  cmd->add_option("--scene", a->import.scene_name,
                  "scene key (default: the folder's name, or its parent's when the "
                  "folder is called images)");
  cmd->add_option("--out", a->out, "dataset root (pixelSplat chunks)")->required();
  cmd->add_option("--split", a->split, "split folder under the root")->capture_default_str();
  cmd->add_option("--context", a->context,
                  "two context frame indices (in the imported frame order: sorted by name) "
                  "for evaluation_index.json")
      ->expected(2);
  cmd->add_option("--target", a->target, "target frame indices for evaluation_index.json");
  cmd->add_flag("--skip-unmatched", a->import.skip_unmatched,
                "leave out photos the model does not mention and model images without a file (default: refuse)");
  cmd->add_flag("--force", a->force, "replace a scene of the same key in index.json / evaluation_index.json");
  cmd->callback([a] { run_import(*a); });
}

}  // namespace uplvsm::cli
