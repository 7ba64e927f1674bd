// `uplvsm dataset import`: bring your own scene. A photo folder (with a COLMAP text model or a nerfstudio
// transforms.json when poses are known) becomes one pixelSplat chunk ROOT/SPLIT/<scene>.torch, merged into the
// split's index.json, optionally into ROOT/evaluation_index.json (the file `eval` and `render` read by default),
// and, for photos without poses, listed in ROOT/SPLIT/unposed.json so tools needing real poses can refuse it.
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/data/dataset_import.h"

namespace uplvsm::cli {

namespace {

using ImportArgs = data::DatasetImportOptions;

void print_import_summary(const ImportArgs& a, const data::DatasetImport& imported) {
  const auto& result = imported.result;
  const std::string& key = result.scene.key;
  const int64_t n = result.scene.cameras.size(0);
  for (const auto& w : result.warnings) std::cout << "warning: " << w << "\n";
  if (!imported.stale_eval.empty()) std::cout << "warning: " << imported.stale_eval << "\n";
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
      imported.chunk_path, a.context.empty() ? "" : " + evaluation_index.json");
}

void run_import(const ImportArgs& a) {
  const auto imported = data::import_into_dataset(a);
  print_import_summary(a, imported);
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
