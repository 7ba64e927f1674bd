// `uplvsm dataset import`'s writing (data/dataset_import.h).
#include "uplvsm/data/dataset_import.h"

#include <algorithm>
#include <filesystem>
#include <map>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "uplvsm/core/json_input.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/io/atomic_file.h"

namespace uplvsm::data {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

void write_json(const fs::path& path, const json& j) {
  const std::string text = j.dump(2) + "\n";
  io::write_file_atomic(path.string(), text.data(), text.size());
}

void check_frames(const DatasetImportOptions& a, int64_t n) {
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
void plan_chunk(const DatasetImportOptions& a, const std::string& key, ImportPlan& plan) {
  const std::string& chunk_name = plan.chunk_name;
  const fs::path& chunk_path = plan.chunk_path;
  if (fs::is_directory(plan.split_dir)) plan.index = read_chunk_index(plan.split_dir.string());
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

void plan_eval_index(const DatasetImportOptions& a, const std::string& key, int64_t n, ImportPlan& plan) {
  const fs::path& eval_path = plan.eval_path;
  if (!fs::exists(eval_path)) return;
  // Merged as raw JSON: read_eval_index (used here to validate, naming the file and key) drops null entries and
  // unknown fields, which must survive the merge.
  const auto entries = read_eval_index(eval_path.string());
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
ImportPlan plan_import(const DatasetImportOptions& a, const std::string& key, int64_t n) {
  ImportPlan plan;
  const fs::path root(a.out);
  plan.split_dir = root / a.split;
  plan.chunk_name = key + ".torch";
  plan.chunk_path = plan.split_dir / plan.chunk_name;
  plan_chunk(a, key, plan);
  plan.eval_path = root / "evaluation_index.json";
  plan_eval_index(a, key, n, plan);
  plan.unposed_path = plan.split_dir / "unposed.json";
  const auto unposed_list = read_unposed_keys(plan.split_dir.string());
  plan.unposed.insert(unposed_list.begin(), unposed_list.end());
  return plan;
}

// The chunk, the split's index, unposed.json (only when it changes) and the evaluation entry.
void write_import(const DatasetImportOptions& a, const ImportedScene& result, ImportPlan& plan) {
  const std::string& key = result.scene.key;
  fs::create_directories(plan.split_dir);
  write_chunk(plan.chunk_path.string(), {result.scene});  // atomic
  plan.index[key] = plan.chunk_name;
  write_chunk_index(plan.split_dir.string(), plan.index);
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

}  // namespace

DatasetImport import_into_dataset(const DatasetImportOptions& a) {
  if ((a.context.empty()) != (a.target.empty()))
    throw std::runtime_error("dataset import: --context and --target go together");
  DatasetImport out;
  out.result = import_scene(a.import);
  const int64_t n = out.result.scene.cameras.size(0);
  check_frames(a, n);
  auto plan = plan_import(a, out.result.scene.key, n);
  write_import(a, out.result, plan);
  out.chunk_path = plan.chunk_path.string();
  out.stale_eval = plan.stale_eval;
  return out;
}

}  // namespace uplvsm::data
