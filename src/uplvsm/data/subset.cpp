#include "uplvsm/data/subset.h"

#include <fstream>
#include <set>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "uplvsm/core/json_input.h"
#include "uplvsm/io/atomic_file.h"

namespace uplvsm::data {

using nlohmann::json;

const std::vector<OfficialSubset>& official_subsets() {
  static const std::vector<OfficialSubset> subsets = {
      {"little", 76, 1202}, {"medium", 304, 4121}, {"large", 1216, 16449}, {"full", 4866, 66033}};
  return subsets;
}

std::optional<OfficialSubset> find_official_subset(const std::string& name) {
  for (const auto& s : official_subsets())
    if (s.name == name) return s;
  return std::nullopt;
}

namespace {

// The split's chunk files in name order with the scenes of each (the dataset is sorted by chunk, then key).
std::vector<std::pair<std::string, std::vector<std::string>>> scenes_by_chunk(const ChunkDataset& dataset) {
  std::vector<std::pair<std::string, std::vector<std::string>>> chunks;
  for (int64_t i = 0; i < dataset.size(); ++i) {
    if (chunks.empty() || chunks.back().first != dataset.chunk_name(i)) chunks.push_back({dataset.chunk_name(i), {}});
    chunks.back().second.push_back(dataset.key(i));
  }
  return chunks;
}

}  // namespace

SubsetManifest select_subset(const ChunkDataset& dataset, const SubsetRequest& request) {
  const int given = !request.name.empty() + (request.chunks > 0) + (request.scenes > 0);
  if (given != 1)
    throw std::runtime_error("select_subset: give exactly one of a subset name, a chunk count or a scene count");
  SubsetManifest m;
  m.split = dataset.split();
  int64_t want_chunks = request.chunks, want_scenes = request.scenes;
  const bool chunked = dataset.layout() == ChunkDataset::Layout::Chunks;
  bool everything = false;
  if (!request.name.empty()) {
    const auto official = find_official_subset(request.name);
    if (!official)
      throw std::runtime_error(
          fmt::format("select_subset: unknown subset '{}' (little, medium, large, full)", request.name));
    m.name = official->name;
    m.official_scenes = official->scenes;
    everything = official->name == "full";
    // Chunks are what the official README counts; an LVSM split has none, so its scenes are counted instead.
    if (chunked)
      want_chunks = official->chunks;
    else
      want_scenes = official->scenes;
  } else {
    m.name = want_chunks > 0 ? fmt::format("chunks_{}", want_chunks) : fmt::format("scenes_{}", want_scenes);
  }
  if (want_chunks > 0 && !chunked)
    throw std::runtime_error(
        fmt::format("select_subset: {}/{} is in the LVSM layout, which has no chunks; select by "
                    "scene count",
                    dataset.root(), dataset.split()));
  if (want_chunks > 0) {
    const auto chunks = scenes_by_chunk(dataset);
    if (!everything && want_chunks > static_cast<int64_t>(chunks.size()))
      throw std::runtime_error(fmt::format("select_subset: '{}' needs {} chunks but {}/{} has {}", m.name, want_chunks,
                                           dataset.root(), dataset.split(), chunks.size()));
    const size_t take = everything ? chunks.size() : static_cast<size_t>(want_chunks);
    for (size_t c = 0; c < take; ++c) {
      m.chunks.push_back(chunks[c].first);
      m.scenes.insert(m.scenes.end(), chunks[c].second.begin(), chunks[c].second.end());
    }
    m.rule = everything ? "every chunk of the split" : fmt::format("the first {} chunk files in name order", take);
  } else {
    if (!everything && want_scenes > dataset.size())
      throw std::runtime_error(fmt::format("select_subset: '{}' needs {} scenes but {}/{} has {}", m.name, want_scenes,
                                           dataset.root(), dataset.split(), dataset.size()));
    const int64_t take = everything ? dataset.size() : want_scenes;
    for (int64_t i = 0; i < take; ++i) m.scenes.push_back(dataset.key(i));
    m.rule = everything ? "every scene of the split"
                        : fmt::format("the first {} scenes in {} order", take, chunked ? "(chunk, key)" : "list");
  }
  return m;
}

void write_subset_manifest(const std::string& path, const SubsetManifest& m) {
  json j = {{"name", m.name},
            {"split", m.split},
            {"rule", m.rule},
            {"num_chunks", m.chunks.size()},
            {"num_scenes", m.scenes.size()},
            {"official_scenes", m.official_scenes},
            {"chunks", m.chunks},
            {"scenes", m.scenes}};
  const auto text = j.dump(2) + "\n";
  io::write_file_atomic(path, text.data(), text.size());
}

SubsetManifest read_subset_manifest(const std::string& path) {
  auto j = read_json_file(path, "subset manifest");
  auto strings = [&](const char* field) {
    if (!j.contains(field) || !j[field].is_array())
      throw std::runtime_error(fmt::format("subset manifest {}: field '{}' must be an array of strings", path, field));
    std::vector<std::string> out;
    for (const auto& v : j[field]) {
      if (!v.is_string())
        throw std::runtime_error(
            fmt::format("subset manifest {}: field '{}' holds {}, expected strings", path, field, json_excerpt(v)));
      out.push_back(v.get<std::string>());
    }
    return out;
  };
  if (!j.is_object()) throw std::runtime_error(fmt::format("subset manifest {}: expected a JSON object", path));
  SubsetManifest m;
  m.name = j.value("name", "");
  m.split = j.value("split", "");
  m.rule = j.value("rule", "");
  m.official_scenes = j.contains("official_scenes")
                          ? json_integer(j["official_scenes"], "subset manifest " + path + ": official_scenes")
                          : 0;
  m.chunks = j.contains("chunks") ? strings("chunks") : std::vector<std::string>{};
  m.scenes = strings("scenes");
  if (m.scenes.empty()) throw std::runtime_error(fmt::format("subset manifest {}: field 'scenes' is empty", path));
  if (std::set<std::string>(m.scenes.begin(), m.scenes.end()).size() != m.scenes.size())
    throw std::runtime_error(fmt::format("subset manifest {}: field 'scenes' lists a scene twice", path));
  return m;
}

}  // namespace uplvsm::data
