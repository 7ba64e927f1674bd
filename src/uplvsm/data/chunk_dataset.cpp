// pixelSplat chunk I/O (read: io::TorchFile; write: LibTorch's pickler, torch.save zip format) and the cached,
// indexed dataset.
#include "uplvsm/data/chunk_dataset.h"

#include <caffe2/serialize/inline_container.h>
#include <torch/csrc/jit/serialization/export.h>
#include <torch/csrc/jit/serialization/pickle.h>
#include <torch/csrc/jit/serialization/pickler.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <optional>
#include <tuple>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "uplvsm/core/json_input.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"
#include "uplvsm/io/torch_file.h"

namespace uplvsm::data {
namespace fs = std::filesystem;
namespace {

std::string describe(const torch::Tensor& t) {
  return t.defined() ? c10::str(t.scalar_type(), t.sizes()) : std::string("undefined");
}

// Checks one scene's fields against the chunk rules; `where` = "<file>: scene <i> (key <k>)".
void validate_scene(const RawScene& s, const std::string& where) {
  if (!s.timestamps.defined() || s.timestamps.dim() != 1 || s.timestamps.scalar_type() != torch::kInt64)
    throw std::runtime_error(
        fmt::format("{}: field 'timestamps' must be int64 [N], got {}", where, describe(s.timestamps)));
  int64_t n = s.timestamps.size(0);
  if (!s.cameras.defined() || s.cameras.scalar_type() != torch::kFloat32 || s.cameras.dim() != 2 ||
      s.cameras.size(1) != 18)
    throw std::runtime_error(
        fmt::format("{}: field 'cameras' must be float32 [N,18], got {}", where, describe(s.cameras)));
  if (s.cameras.size(0) != n)
    throw std::runtime_error(
        fmt::format("{}: field 'cameras' has {} rows but timestamps has N={}", where, s.cameras.size(0), n));
  if (static_cast<int64_t>(s.images.size()) != n)
    throw std::runtime_error(
        fmt::format("{}: field 'images' has {} entries but timestamps has N={}", where, s.images.size(), n));
  for (size_t j = 0; j < s.images.size(); ++j) {
    const auto& im = s.images[j];
    if (!im.defined() || im.scalar_type() != torch::kUInt8 || im.dim() != 1 || im.numel() == 0)
      throw std::runtime_error(
          fmt::format("{}: field 'images' entry {} must be a non-empty uint8 1-D tensor of JPEG "
                      "bytes, got {}",
                      where, j, describe(im)));
  }
}

using io::PyObject;
using Kind = io::PyObject::Kind;

const PyObject& field(const PyObject& dict, const char* name, const std::string& where) {
  const PyObject* v = dict.get(name);
  if (!v) throw std::runtime_error(fmt::format("{}: missing field '{}'", where, name));
  return *v;
}

std::string string_field(const PyObject& dict, const char* name, const std::string& where) {
  const auto& v = field(dict, name, where);
  if (!v.is(Kind::Str))
    throw std::runtime_error(fmt::format("{}: field '{}' must be a str, got {}", where, name, v.describe()));
  return v.text;
}

torch::Tensor tensor_field(const io::TorchFile& file, const PyObject& dict, const char* name,
                           const std::string& where) {
  const auto& v = field(dict, name, where);
  if (!v.is(Kind::Tensor))
    throw std::runtime_error(fmt::format("{}: field '{}' must be a tensor, got {}", where, name, v.describe()));
  return file.tensor(v).contiguous();
}

RawScene parse_scene(const io::TorchFile& file, const PyObject& item, const std::string& where) {
  if (!item.is(Kind::Dict))
    throw std::runtime_error(fmt::format("{}: expected a dict, got {}", where, item.describe()));
  RawScene s;
  s.key = string_field(item, "key", where);
  std::string at = fmt::format("{} (key {})", where, s.key);
  s.url = string_field(item, "url", at);
  s.timestamps = tensor_field(file, item, "timestamps", at);
  if (s.timestamps.dim() == 1 && c10::isIntegralType(s.timestamps.scalar_type(), false))
    s.timestamps = s.timestamps.to(torch::kInt64);
  s.cameras = tensor_field(file, item, "cameras", at);
  if (s.cameras.is_floating_point()) s.cameras = s.cameras.to(torch::kFloat32);
  const auto& images = field(item, "images", at);
  if (!images.is(Kind::List) && !images.is(Kind::Tuple))
    throw std::runtime_error(
        fmt::format("{}: field 'images' must be a list of tensors, got {}", at, images.describe()));
  s.images.reserve(images.items.size());
  for (size_t j = 0; j < images.items.size(); ++j) {
    const auto& v = *images.items[j];
    if (!v.is(Kind::Tensor))
      throw std::runtime_error(
          fmt::format("{}: field 'images' entry {} must be a tensor, got {}", at, j, v.describe()));
    s.images.push_back(file.tensor(v).contiguous());
  }
  validate_scene(s, at);
  return s;
}

// A tensor that owns exactly its bytes (a view would make torch.save write the whole underlying storage).
torch::Tensor compact(const torch::Tensor& t) {
  auto c = t.contiguous();
  if (c.storage_offset() != 0 || c.storage().nbytes() != static_cast<size_t>(c.nbytes())) c = c.clone();
  return c;
}

// torch::pickle_save, but without TorchScript type tags on lists and dicts (tag_aggregates = false): tagged
// containers unpickle through torch.jit._pickle.restore_type_tag, which torch.load(weights_only=True) - the
// default since torch 2.6 - refuses. Untagged, the file holds only what Python's torch.save itself writes.
std::vector<char> pickle_save_plain(const c10::IValue& value) {
  std::vector<char> pickle;
  torch::jit::Pickler pickler([&](const char* buf, size_t size) { pickle.insert(pickle.end(), buf, buf + size); },
                              /*tensor_table=*/nullptr, /*type_renamer=*/nullptr, /*memoized_class_types=*/nullptr,
                              /*get_tensor_id=*/nullptr, /*tag_aggregates=*/false);
  pickler.protocol();
  pickler.pushIValue(value);
  pickler.stop();
  std::vector<char> container;
  caffe2::serialize::PyTorchStreamWriter writer([&](const void* data, size_t size) {
    const char* bytes = static_cast<const char*>(data);
    container.insert(container.end(), bytes, bytes + size);
    return size;
  });
  torch::jit::writeArchiveAndTensors("data", pickle.data(), pickle.size(), pickler.tensorData(), writer);
  writer.writeEndOfFile();
  return container;
}

}  // namespace

void write_chunk(const std::string& path, const std::vector<RawScene>& scenes) {
  // Generic (Any-typed) lists and dicts, pickled untagged: plain Python lists/dicts for torch.load.
  c10::impl::GenericList list(c10::AnyType::get());
  for (size_t i = 0; i < scenes.size(); ++i) {
    const auto& s = scenes[i];
    validate_scene(s, fmt::format("write_chunk: {}: scene {} (key {})", path, i, s.key));
    c10::impl::GenericDict dict(c10::StringType::get(), c10::AnyType::get());
    dict.insert("url", s.url);
    dict.insert("timestamps", compact(s.timestamps));
    dict.insert("cameras", compact(s.cameras));
    c10::impl::GenericList images(c10::AnyType::get());
    for (const auto& im : s.images) images.push_back(compact(im));
    dict.insert("images", images);
    dict.insert("key", s.key);
    list.push_back(dict);
  }
  std::vector<char> bytes = pickle_save_plain(list);
  io::write_file_atomic(path, bytes.data(), bytes.size());
}

std::vector<RawScene> read_chunk(const std::string& path) {
  // Our bounds-checked torch.save reader, not torch::pickle_load: fuzzing found LibTorch 1.13's in-memory zip
  // reader reading freed memory on a malformed archive (fuzz/, `make fuzz`).
  std::unique_ptr<io::TorchFile> file;
  try {
    file = std::make_unique<io::TorchFile>(path);
  } catch (const std::exception& e) {
    throw std::runtime_error(
        fmt::format("read_chunk: {}: not a readable torch.save file (truncated or corrupt?): {}", path, e.what()));
  }
  const auto& root = file->root();
  if (!root.is(Kind::List))
    throw std::runtime_error(
        fmt::format("read_chunk: {}: expected a list of scene dicts, got {}", path, root.describe()));
  std::vector<RawScene> scenes;
  scenes.reserve(root.items.size());
  try {
    for (size_t i = 0; i < root.items.size(); ++i)
      scenes.push_back(parse_scene(*file, *root.items[i], fmt::format("read_chunk: {}: scene {}", path, i)));
  } catch (const c10::Error& e) {  // a storage record that is missing or truncated
    throw std::runtime_error(fmt::format("read_chunk: {}: corrupt tensor data: {}", path, e.what_without_backtrace()));
  }
  return scenes;
}

std::map<std::string, std::string> read_chunk_index(const std::string& split_dir) {
  std::map<std::string, std::string> index;
  fs::path index_path = fs::path(split_dir) / "index.json";
  if (fs::exists(index_path)) {
    auto j = read_json_file(index_path.string());
    if (!j.is_object())
      throw std::runtime_error(fmt::format("{}: expected an object {{key: chunk file}}", index_path.string()));
    for (auto& [key, value] : j.items()) {
      if (!value.is_string())
        throw std::runtime_error(
            fmt::format("{}: value of key '{}' must be a chunk file name", index_path.string(), key));
      index[key] = value.get<std::string>();
    }
    return index;
  }
  // No index: every *.torch file of the folder, read once to learn its keys.
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(split_dir))
    if (e.is_regular_file() && e.path().extension() == ".torch") files.push_back(e.path().filename().string());
  std::sort(files.begin(), files.end());
  for (const auto& f : files)
    for (const auto& s : read_chunk((fs::path(split_dir) / f).string())) index[s.key] = f;
  return index;
}

void write_chunk_index(const std::string& split_dir, const std::map<std::string, std::string>& index) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [key, file] : index) j[key] = file;
  std::string text = j.dump(2) + "\n";
  io::write_file_atomic((fs::path(split_dir) / "index.json").string(), text.data(), text.size());
}

std::vector<std::string> read_unposed_keys(const std::string& split_dir) {
  const auto path = fs::path(split_dir) / "unposed.json";
  if (!fs::exists(path)) return {};
  auto j = read_json_file(path.string());
  if (!j.is_array()) throw std::runtime_error(fmt::format("{}: expected an array of scene keys", path.string()));
  std::vector<std::string> keys;
  for (const auto& k : j) {
    if (!k.is_string())
      throw std::runtime_error(fmt::format("{}: entry {} is not a scene key", path.string(), json_excerpt(k)));
    keys.push_back(k.get<std::string>());
  }
  return keys;
}

namespace {

bool has_chunks(const std::string& dir) {
  if (fs::exists(fs::path(dir) / "index.json")) return true;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".torch") return true;
  return false;
}

}  // namespace

ChunkDataset::ChunkDataset(std::string root, std::string split, int cache_chunks, int64_t cache_bytes)
    : root_(std::move(root)), split_(std::move(split)) {
  dir_ = (fs::path(root_) / split_).string();
  if (!fs::is_directory(dir_))
    throw std::runtime_error(fmt::format("ChunkDataset: {} is not a folder (expected root/{{train,test}})", dir_));
  info_ = read_dataset_info(root_);
  if (!has_chunks(dir_) && is_lvsm_split(dir_)) {
    layout_ = Layout::Lvsm;
    cache_chunks *= 16;
    // Keys are the metadata files' stems (process_data.py names them after the scene); checked when read.
    for (const auto& path : list_lvsm_scenes(dir_)) entries_.push_back({fs::path(path).stem().string(), path});
  } else {
    for (const auto& [key, file] : read_chunk_index(dir_)) {
      if (!fs::exists(fs::path(dir_) / file))
        throw std::runtime_error(
            fmt::format("ChunkDataset: {}/index.json maps key {} to missing file {}", dir_, key, file));
      entries_.push_back({key, file});
    }
  }
  std::sort(entries_.begin(), entries_.end(),
            [](const Entry& a, const Entry& b) { return std::tie(a.chunk, a.key) < std::tie(b.chunk, b.key); });
  for (size_t i = 1; i < entries_.size(); ++i)
    if (entries_[i].key == entries_[i - 1].key)
      throw std::runtime_error(fmt::format("ChunkDataset: {}: scene {} appears twice", dir_, entries_[i].key));
  for (auto& k : read_unposed_keys(dir_)) unposed_.insert(std::move(k));
  rebuild_lookup();
  cache_ = std::make_unique<ChunkCache<LoadedChunk>>(std::max(1, cache_chunks), cache_bytes);
}

void ChunkDataset::rebuild_lookup() {
  num_frames_ = std::make_unique<std::atomic<int64_t>[]>(entries_.size());
  by_key_.clear();
  chunk_starts_.clear();
  for (size_t i = 0; i < entries_.size(); ++i) {
    by_key_[entries_[i].key] = static_cast<int64_t>(i);
    num_frames_[i].store(-1);
    if (i == 0 || entries_[i].chunk != entries_[i - 1].chunk) chunk_starts_.push_back(static_cast<int64_t>(i));
  }
}

void ChunkDataset::keep_only(const std::vector<std::string>& keys) {
  std::set<std::string> wanted(keys.begin(), keys.end());
  std::vector<std::string> missing;
  for (const auto& k : wanted)
    if (!by_key_.count(k)) missing.push_back(k);
  if (!missing.empty())
    throw std::runtime_error(
        fmt::format("ChunkDataset {}: {} of the {} requested scenes are not in the split (first: "
                    "{})",
                    dir_, missing.size(), wanted.size(), missing.front()));
  std::vector<Entry> kept;
  for (const auto& e : entries_)
    if (wanted.count(e.key)) kept.push_back(e);
  entries_ = std::move(kept);
  rebuild_lookup();
}

bool ChunkDataset::poses_known(int64_t i) const { return !unposed_.count(key(i)); }

const std::string& ChunkDataset::chunk_name(int64_t i) const {
  check_index(i);
  return entries_[i].chunk;
}

void ChunkDataset::check_index(int64_t i) const {
  if (i < 0 || i >= size())
    throw std::out_of_range(fmt::format("ChunkDataset {}: scene index {} out of range [0, {})", dir_, i, size()));
}

const std::string& ChunkDataset::key(int64_t i) const {
  check_index(i);
  return entries_[i].key;
}

std::string ChunkDataset::chunk_path(int64_t i) const {
  check_index(i);
  return (fs::path(dir_) / entries_[i].chunk).string();
}

int64_t ChunkDataset::find(const std::string& key) const {
  auto it = by_key_.find(key);
  return it == by_key_.end() ? -1 : it->second;
}

std::shared_ptr<const ChunkDataset::LoadedChunk> ChunkDataset::load_chunk(const std::string& chunk) const {
  return cache_->get(chunk, [&] { return read_loaded_chunk(chunk); });
}

std::pair<ChunkDataset::ChunkPtr, int64_t> ChunkDataset::read_loaded_chunk(const std::string& chunk) const {
  ++chunk_reads_;
  auto loaded = std::make_shared<LoadedChunk>();
  if (layout_ == Layout::Lvsm) {
    loaded->scenes.push_back(lvsm_scene(chunk));
  } else {
    for (auto& scene : read_chunk((fs::path(dir_) / chunk).string())) loaded->scenes.push_back(chunk_scene(scene));
  }
  int64_t bytes = 0;
  for (size_t j = 0; j < loaded->scenes.size(); ++j) {
    const auto& scene = *loaded->scenes[j];
    loaded->by_key[scene.key()] = j;
    bytes += scene.bytes();
    const int64_t idx = find(scene.key());
    if (idx >= 0) num_frames_[idx].store(scene.num_frames());
  }
  return {std::move(loaded), bytes};
}

const StoredScene& ChunkDataset::scene_ref(int64_t i, ChunkPtr& holder) const {
  check_index(i);
  const Entry& e = entries_[i];
  holder = load_chunk(e.chunk);
  auto it = holder->by_key.find(e.key);
  if (it == holder->by_key.end())
    throw std::runtime_error(
        fmt::format("ChunkDataset: {}/index.json says scene {} is in {}, but that chunk has "
                    "no such key",
                    dir_, e.key, e.chunk));
  return *holder->scenes[it->second];
}

int64_t ChunkDataset::num_frames(int64_t i) const {
  check_index(i);
  int64_t n = num_frames_[i].load();
  if (n >= 0) return n;
  ChunkPtr holder;
  return scene_ref(i, holder).num_frames();
}

RawScene ChunkDataset::scene(int64_t i) const {
  ChunkPtr holder;
  return scene_ref(i, holder).raw();
}

SceneViews ChunkDataset::load_views(int64_t i, const std::vector<int64_t>& frames, const PreprocessOptions& opt,
                                    FrameSizePolicy other_sizes) const {
  ChunkPtr holder;
  const StoredScene& s = scene_ref(i, holder);
  const int64_t n = s.num_frames();
  const std::string where = fmt::format("{}: scene {}", chunk_path(i), s.key());
  if (frames.empty()) throw std::runtime_error(fmt::format("{}: no frames requested", where));
  for (int64_t f : frames)
    if (f < 0 || f >= n)
      throw std::runtime_error(fmt::format("{}: frame {} out of range (scene has {} frames)", where, f, n));
  const bool resize = other_sizes == FrameSizePolicy::Resize;
  const auto first = s.frame_bytes(0);
  auto [h0, w0] = io::image_size(first.data_ptr<uint8_t>(), first.numel(), where + " frame 0");
  std::vector<torch::Tensor> decoded, cameras;
  decoded.reserve(frames.size());
  std::optional<std::pair<int, int>> stacked;  // the output size of the first requested frame
  int64_t resized = 0;
  for (int64_t f : frames) {
    const auto bytes = f == 0 ? first : s.frame_bytes(f);
    std::string what = fmt::format("{} frame {}", where, f);
    auto img = io::decode_image(bytes.data_ptr<uint8_t>(), bytes.numel(), what);
    int h = static_cast<int>(img.size(0)), w = static_cast<int>(img.size(1));
    const auto out = preprocessed_size(h, w, opt);
    if (!stacked) stacked = out;
    const bool other_size = h != h0 || w != w0;
    if ((other_size && !resize) || out != *stacked)
      throw BadFrameError(
          fmt::format("{}: frame is {}x{} but frame 0 is {}x{} ({})", what, h, w, h0, w0,
                      resize ? "another output size without a square crop" : "pixelSplat skips such frames"),
          s.key(), f, h0, w0, h, w);
    resized += other_size ? 1 : 0;
    auto row = s.camera_row(f, h, w);
    if (!torch::isfinite(row).all().item<bool>())
      throw std::runtime_error(fmt::format("{}: field 'cameras' has a NaN/Inf value", what));
    decoded.push_back(img);
    cameras.push_back(row);
  }
  SceneViews views = preprocess(decoded, torch::stack(cameras), opt, where);
  views.frames = frames;
  views.resized_frames = resized;
  return views;
}

}  // namespace uplvsm::data
