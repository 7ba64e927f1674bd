#include "uplvsm/data/lvsm_layout.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "uplvsm/core/json_input.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"

namespace uplvsm::data {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::vector<uint8_t> read_bytes(const fs::path& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open image {}", what, path.string()));
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::vector<double> numbers(const json& j, size_t count, const std::string& what) {
  std::vector<double> out;
  auto take = [&](const json& v) {
    if (!v.is_number()) throw std::runtime_error(what + ": expected numbers, got " + json_excerpt(v));
    out.push_back(v.get<double>());
  };
  if (!j.is_array()) throw std::runtime_error(what + ": expected an array, got " + json_excerpt(j));
  for (const auto& v : j) {
    if (v.is_array())
      for (const auto& x : v) take(x);
    else
      take(v);
  }
  if (out.size() != count)
    throw std::runtime_error(fmt::format("{}: expected {} numbers, got {}", what, count, out.size()));
  for (double x : out)
    if (!std::isfinite(x)) throw std::runtime_error(what + ": has a NaN/Inf value");
  return out;
}

// Image paths may be absolute (official), relative to the split folder, or relative to the JSON's folder. An
// absolute path that is gone (the dataset was moved) is looked up where process_data.py puts images.
fs::path resolve_image(const std::string& image_path, const fs::path& metadata_path, const std::string& scene) {
  fs::path p(image_path);
  const auto split_dir = metadata_path.parent_path().parent_path();
  if (p.is_absolute()) {
    if (fs::exists(p)) return p;
    const auto moved = split_dir / "images" / scene / p.filename();
    return fs::exists(moved) ? moved : p;
  }
  if (fs::exists(split_dir / p)) return split_dir / p;
  return metadata_path.parent_path() / p;
}

}  // namespace

LvsmSceneMetadata read_lvsm_metadata(const std::string& metadata_path) {
  auto j = read_json_file(metadata_path, "LVSM metadata");
  if (!j.is_object() || !j.contains("frames") || !j["frames"].is_array() || j["frames"].empty())
    throw std::runtime_error(
        fmt::format("LVSM metadata {}: expected an object with a non-empty 'frames' array", metadata_path));
  LvsmSceneMetadata m;
  m.key = j.contains("scene_name") && j["scene_name"].is_string() ? j["scene_name"].get<std::string>()
                                                                  : fs::path(metadata_path).stem().string();
  if (m.key.empty()) throw std::runtime_error(fmt::format("LVSM metadata {}: empty scene_name", metadata_path));
  for (size_t i = 0; i < j["frames"].size(); ++i) {
    const auto& f = j["frames"][i];
    const std::string what = fmt::format("LVSM metadata {}: frames[{}]", metadata_path, i);
    if (!f.is_object()) throw std::runtime_error(what + ": expected an object");
    for (const char* field : {"image_path", "fxfycxcy", "w2c"})
      if (!f.contains(field)) throw std::runtime_error(fmt::format("{}: missing field '{}'", what, field));
    if (!f["image_path"].is_string()) throw std::runtime_error(what + ".image_path: expected a string");
    const auto k = numbers(f["fxfycxcy"], 4, what + ".fxfycxcy");
    const size_t w2c_count = f["w2c"].is_array() && f["w2c"].size() == 3 ? 12 : 16;
    const auto w2c = numbers(f["w2c"], w2c_count, what + ".w2c");
    m.image_paths.push_back(resolve_image(f["image_path"].get<std::string>(), metadata_path, m.key).string());
    m.fxfycxcy.push_back({k[0], k[1], k[2], k[3]});
    std::array<double, 12> rows{};
    std::copy(w2c.begin(), w2c.begin() + 12, rows.begin());
    m.w2c.push_back(rows);
  }
  return m;
}

torch::Tensor lvsm_camera_row(const LvsmSceneMetadata& m, int64_t i, int height, int width) {
  auto row = torch::zeros({18}, torch::kFloat32);
  auto r = row.accessor<float, 1>();
  const auto& k = m.fxfycxcy.at(static_cast<size_t>(i));
  r[0] = static_cast<float>(k[0] / width);
  r[1] = static_cast<float>(k[1] / height);
  r[2] = static_cast<float>(k[2] / width);
  r[3] = static_cast<float>(k[3] / height);
  for (int e = 0; e < 12; ++e) r[6 + e] = static_cast<float>(m.w2c[static_cast<size_t>(i)][e]);
  return row;
}

bool is_lvsm_split(const std::string& split_dir) {
  return fs::exists(fs::path(split_dir) / "full_list.txt") || fs::is_directory(fs::path(split_dir) / "metadata");
}

std::vector<std::string> list_lvsm_scenes(const std::string& split_dir) {
  std::vector<std::string> paths;
  const auto list = fs::path(split_dir) / "full_list.txt";
  const auto meta = fs::path(split_dir) / "metadata";
  if (fs::exists(list)) {
    paths = read_full_list(list.string());
    for (auto& p : paths)
      if (!fs::exists(p) && fs::exists(meta / fs::path(p).filename())) p = (meta / fs::path(p).filename()).string();
  } else {
    if (!fs::is_directory(meta))
      throw std::runtime_error(fmt::format("LVSM split {}: neither full_list.txt nor metadata/ found", split_dir));
    for (const auto& e : fs::directory_iterator(meta))
      if (e.path().extension() == ".json") paths.push_back(e.path().string());
    std::sort(paths.begin(), paths.end());
  }
  if (paths.empty()) throw std::runtime_error(fmt::format("LVSM split {}: no scenes listed", split_dir));
  return paths;
}

RawScene read_lvsm_scene(const std::string& metadata_path) {
  const auto m = read_lvsm_metadata(metadata_path);
  RawScene s;
  s.key = m.key;
  const int64_t n = m.size();
  s.cameras = torch::zeros({n, 18}, torch::kFloat32);
  for (int64_t i = 0; i < n; ++i) {
    const std::string what = fmt::format("LVSM metadata {}: frames[{}]", metadata_path, i);
    auto bytes = read_bytes(m.image_paths[i], what);
    auto [h, w] = io::image_size(bytes.data(), bytes.size(), what + ".image_path");
    s.cameras[i] = lvsm_camera_row(m, i, h, w);
    auto t = torch::empty({static_cast<int64_t>(bytes.size())}, torch::kUInt8);
    std::copy(bytes.begin(), bytes.end(), t.data_ptr<uint8_t>());
    s.images.push_back(t);
  }
  s.timestamps = torch::arange(n, torch::kInt64);  // the layout keeps no timestamps: frame order
  return s;
}

std::string write_lvsm_scene(const std::string& split_dir, const RawScene& scene) {
  const auto root = fs::absolute(split_dir);
  json frames = json::array();
  auto cam = scene.cameras.to(torch::kFloat32).contiguous();
  auto c = cam.accessor<float, 2>();
  for (size_t i = 0; i < scene.images.size(); ++i) {
    const auto& bytes = scene.images[i];
    const std::string what = fmt::format("scene {} frame {}", scene.key, i);
    auto img = io::decode_image(bytes.data_ptr<uint8_t>(), bytes.numel(), what);
    const double h = static_cast<double>(img.size(0)), w = static_cast<double>(img.size(1));
    const auto path = root / "images" / scene.key / fmt::format("{:05d}.png", i);
    const auto png = io::encode_png(img);
    io::write_file_atomic(path.string(), png.data(), png.size());
    json w2c = json::array();
    for (int r = 0; r < 3; ++r) w2c.push_back({c[i][6 + 4 * r], c[i][7 + 4 * r], c[i][8 + 4 * r], c[i][9 + 4 * r]});
    w2c.push_back({0.0, 0.0, 0.0, 1.0});
    frames.push_back({{"image_path", path.string()},
                      {"fxfycxcy", {c[i][0] * w, c[i][1] * h, c[i][2] * w, c[i][3] * h}},
                      {"w2c", w2c}});
  }
  const auto meta = root / "metadata" / (scene.key + ".json");
  const auto text = json{{"scene_name", scene.key}, {"frames", frames}}.dump(2);
  io::write_file_atomic(meta.string(), text.data(), text.size());
  return meta.string();
}

std::vector<std::string> read_full_list(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(fmt::format("LVSM list {}: cannot open", path));
  std::vector<std::string> out;
  std::string line;
  while (std::getline(in, line)) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (line.empty()) continue;
    fs::path p(line);
    out.push_back(p.is_absolute() ? line : (fs::path(path).parent_path() / p).string());
  }
  return out;
}

void write_full_list(const std::string& split_dir, std::vector<std::string> metadata_paths) {
  std::sort(metadata_paths.begin(), metadata_paths.end());
  std::string text;
  for (const auto& p : metadata_paths) text += p + "\n";
  io::write_file_atomic((fs::path(split_dir) / "full_list.txt").string(), text.data(), text.size());
}

ConversionResult chunks_to_lvsm(const std::string& chunk_split_dir, const std::string& lvsm_split_dir,
                                const ConversionProgress& progress) {
  const auto index = read_chunk_index(chunk_split_dir);
  std::map<std::string, int64_t> per_chunk;  // chunk file -> scenes listed in the index
  for (const auto& [key, file] : index) ++per_chunk[file];
  ConversionResult r;
  std::vector<std::string> written;
  for (const auto& [file, count] : per_chunk) {
    for (const auto& scene : read_chunk((fs::path(chunk_split_dir) / file).string())) {
      if (!index.count(scene.key)) continue;  // a scene the index leaves out stays out
      written.push_back(write_lvsm_scene(lvsm_split_dir, scene));
      ++r.scenes;
      r.frames += static_cast<int64_t>(scene.images.size());
      if (progress) progress(r.scenes, static_cast<int64_t>(index.size()));
    }
  }
  write_full_list(lvsm_split_dir, written);
  r.files = static_cast<int64_t>(written.size());
  return r;
}

ConversionResult lvsm_to_chunks(const std::string& lvsm_split_dir, const std::string& chunk_split_dir,
                                int64_t scenes_per_chunk, const ConversionProgress& progress) {
  if (scenes_per_chunk < 1) throw std::runtime_error("lvsm_to_chunks: scenes_per_chunk must be >= 1");
  const auto paths = list_lvsm_scenes(lvsm_split_dir);
  ConversionResult r;
  std::map<std::string, std::string> index;
  std::vector<RawScene> pending;
  auto flush = [&] {
    if (pending.empty()) return;
    const auto name = fmt::format("{:06d}.torch", r.files);
    write_chunk((fs::path(chunk_split_dir) / name).string(), pending);
    for (const auto& s : pending) {
      if (!index.emplace(s.key, name).second)
        throw std::runtime_error(fmt::format("LVSM split {}: scene name '{}' appears twice", lvsm_split_dir, s.key));
    }
    pending.clear();
    ++r.files;
  };
  for (const auto& p : paths) {
    pending.push_back(read_lvsm_scene(p));
    ++r.scenes;
    r.frames += static_cast<int64_t>(pending.back().images.size());
    if (static_cast<int64_t>(pending.size()) == scenes_per_chunk) flush();
    if (progress) progress(r.scenes, static_cast<int64_t>(paths.size()));
  }
  flush();
  write_chunk_index(chunk_split_dir, index);
  return r;
}

}  // namespace uplvsm::data
