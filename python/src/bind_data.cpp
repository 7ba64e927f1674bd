// uplvsm.data (native part): datasets in the pixelSplat chunk or LVSM layout, and users' photos, as view dicts of
// tensors. The torch.utils.data.Dataset around them is Python (uplvsm/data.py).
#include "binding_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/photo.h"

namespace uplvsm::python {

namespace {

py::dict views_dict(const data::SceneViews& v) {
  py::dict out;
  out["images"] = v.images;
  out["fxfycxcy"] = v.fxfycxcy;
  out["c2w"] = v.c2w;
  out["frames"] = torch::tensor(v.frames, torch::kInt64);
  return out;
}

data::PreprocessOptions preprocess_options(int image_size, int patch_size, bool square_crop, const char* where) {
  if (image_size <= 0 || patch_size <= 0)
    throw py::value_error(std::string(where) + ": image_size and patch_size must be > 0, got " +
                          std::to_string(image_size) + " and " + std::to_string(patch_size));
  return {image_size, patch_size, square_crop};
}

int64_t checked_index(const data::ChunkDataset& d, int64_t i) {
  if (i < 0 || i >= d.size())
    throw py::index_error("scene index " + std::to_string(i) + " is out of range for " + std::to_string(d.size()) +
                          " scenes of " + d.root() + "/" + d.split());
  return i;
}

// One split of a dataset, read in place: keys, frame counts and preprocessed views by scene index.
void bind_chunk_dataset(py::module_& m) {
  py::class_<data::ChunkDataset>(m, "ChunkDataset",
                                 "One split of a dataset, read in place (native; use uplvsm.data.Dataset).")
      .def(py::init([](const std::string& root, const std::string& split, int cache_chunks) {
             if (cache_chunks < 1) throw py::value_error("cache_chunks must be >= 1");
             py::gil_scoped_release release;
             return std::make_unique<data::ChunkDataset>(root, split, cache_chunks);
           }),
           py::arg("root"), py::arg("split"), py::arg("cache_chunks") = 4)
      .def("__len__", &data::ChunkDataset::size)
      .def_property_readonly("root", &data::ChunkDataset::root)
      .def_property_readonly("split", &data::ChunkDataset::split)
      .def_property_readonly("layout",
                             [](const data::ChunkDataset& d) {
                               return d.layout() == data::ChunkDataset::Layout::Chunks ? "chunks" : "lvsm";
                             })
      .def("keys",
           [](const data::ChunkDataset& d) {
             std::vector<std::string> keys;
             for (int64_t i = 0; i < d.size(); ++i) keys.push_back(d.key(i));
             return keys;
           })
      .def(
          "key", [](const data::ChunkDataset& d, int64_t i) { return d.key(checked_index(d, i)); }, py::arg("i"))
      .def("find", &data::ChunkDataset::find, py::arg("key"))
      .def(
          "poses_known", [](const data::ChunkDataset& d, int64_t i) { return d.poses_known(checked_index(d, i)); },
          py::arg("i"))
      .def(
          "num_frames",
          [](const data::ChunkDataset& d, int64_t i) {
            checked_index(d, i);
            py::gil_scoped_release release;
            return d.num_frames(i);
          },
          py::arg("i"))
      .def(
          "load_views",
          [](const data::ChunkDataset& d, int64_t i, const std::vector<int64_t>& frames, int image_size, int patch_size,
             bool square_crop) {
            checked_index(d, i);
            if (frames.empty()) throw py::value_error("load_views: frames is empty");
            const auto opt = preprocess_options(image_size, patch_size, square_crop, "load_views");
            data::SceneViews v;
            {
              py::gil_scoped_release release;
              v = d.load_views(i, frames, opt);
            }
            return views_dict(v);
          },
          py::arg("i"), py::arg("frames"), py::arg("image_size"), py::arg("patch_size"), py::arg("square_crop"));
}

void bind_photos(py::module_& m) {
  m.def(
      "load_photos",
      [](const std::vector<std::string>& paths, int image_size, double fov, int patch_size, bool square_crop) {
        const auto opt = preprocess_options(image_size, patch_size, square_crop, "load_photos");
        data::SceneViews v;
        {
          py::gil_scoped_release release;
          v = data::load_photos(paths, fov, opt);
        }
        return views_dict(v);
      },
      py::arg("paths"), py::arg("image_size") = 224, py::arg("fov") = 60.0, py::arg("patch_size") = 14,
      py::arg("square_crop") = true,
      R"(Your own photos (JPEG/PNG paths, turned upright by their EXIF orientation) as views of one scene, preprocessed
like the training data (PIL-exact LANCZOS resize to image_size rows, centred square crop), with a pinhole camera of
horizontal field of view `fov` degrees: {"images": [V, 3, H, W], "fxfycxcy": [V, 4] pixels, "c2w": [V, 4, 4]
identity, "frames": [V]}.)");
}

}  // namespace

void bind_data(py::module_& root) {
  auto m = root.def_submodule("data", "Datasets (pixelSplat chunks, LVSM layout) and photos as tensors.");
  bind_chunk_dataset(m);
  bind_photos(m);
}

}  // namespace uplvsm::python
