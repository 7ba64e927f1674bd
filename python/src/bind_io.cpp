// uplvsm.io: weight and tensor files without Python's unpickler (torch.save files, safetensors), images, MP4 video.
#include <map>
#include <unordered_map>
#include <unordered_set>

#include "binding_util.h"
#include "uplvsm/io/image.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/torch_file.h"
#include "uplvsm/io/video.h"

namespace uplvsm::python {

namespace {

// A call in the pickle that was not run (anything but dicts, tensors, sets and parameters): its function's name and
// arguments, so a caller can still read e.g. an argparse.Namespace's fields.
struct OpaqueCall {
  std::string function;
  py::object args;
};

// The pickled object graph as Python objects. Shared objects stay shared (each converted once) and a self-reference
// is an error, so a hostile file can neither recurse without end nor blow up through repeated references.
class PickleToPython {
 public:
  explicit PickleToPython(const io::TorchFile& file) : file_(file) {}

  py::object convert(const io::PyObject& o, int depth = 0) {
    using Kind = io::PyObject::Kind;
    if (depth > kMaxDepth)
      throw py::value_error(file_.path() + ": pickle nests deeper than " + std::to_string(kMaxDepth) + " levels");
    if (auto hit = done_.find(&o); hit != done_.end()) return hit->second;
    if (!open_.insert(&o).second) throw py::value_error(file_.path() + ": pickle holds a self-referencing object");
    py::object out;
    switch (o.kind) {
      case Kind::None: out = py::none(); break;
      case Kind::Bool: out = py::bool_(o.boolean); break;
      case Kind::Int: out = py::int_(o.integer); break;
      case Kind::BigInt:
        out = py::module_::import("builtins")
                  .attr("int")
                  .attr("from_bytes")(py::bytes(o.text), "little", py::arg("signed") = true);
        break;
      case Kind::Float: out = py::float_(o.real); break;
      case Kind::Str: out = py::str(o.text); break;
      case Kind::Bytes: out = py::bytes(o.text); break;
      case Kind::List:
      case Kind::Tuple:
      case Kind::Set: {
        py::list items;
        for (const auto& item : o.items) items.append(convert(*item, depth + 1));
        out = o.kind == Kind::List    ? py::object(items)
              : o.kind == Kind::Tuple ? py::object(py::tuple(items))
                                      : py::object(py::set(items));
        break;
      }
      case Kind::Dict: {
        py::dict d;
        for (const auto& [k, v] : o.dict) d[convert(*k, depth + 1)] = convert(*v, depth + 1);
        out = d;
        break;
      }
      case Kind::Tensor: out = py::cast(file_.tensor(o)); break;
      case Kind::Global: out = py::cast(OpaqueCall{o.text, py::none()}); break;
      case Kind::Call: {
        const auto& callee = o.items.at(0);
        out = py::cast(OpaqueCall{callee->kind == Kind::Global ? callee->text : callee->describe(),
                                  convert(*o.items.at(1), depth + 1)});
        break;
      }
      case Kind::Storage: out = py::cast(OpaqueCall{"storage " + o.tensor.storage_key, py::none()}); break;
    }
    open_.erase(&o);
    done_.emplace(&o, out);
    return out;
  }

 private:
  static constexpr int kMaxDepth = 200;
  const io::TorchFile& file_;
  std::unordered_map<const io::PyObject*, py::object> done_;
  std::unordered_set<const io::PyObject*> open_;
};

// float [F, 3, H, W] in [0, 1] or uint8 [F, H, W, 3] -> uint8 HWC frames.
std::vector<torch::Tensor> video_frames(const torch::Tensor& frames) {
  if (frames.dim() == 4 && frames.scalar_type() == torch::kUInt8 && frames.size(3) == 3) {
    return frames.cpu().contiguous().unbind(0);
  }
  check_tensor(frames, "write_mp4", "frames", {-1, 3, -1, -1}, "float [F, 3, H, W] in [0, 1] or uint8 [F, H, W, 3]");
  std::vector<torch::Tensor> out;
  for (const auto& f : frames.detach().cpu().unbind(0)) out.push_back(io::to_u8_hwc(f));
  return out;
}

// torch.save files, read without running their pickle: OpaqueCall stands for any call it does not run.
void bind_torch_file(py::module_& m) {
  py::class_<OpaqueCall>(m, "OpaqueCall",
                         "A call in a torch.save file that read_torch_file did not run: its function's name and "
                         "arguments.")
      .def_readonly("function", &OpaqueCall::function)
      .def_readonly("args", &OpaqueCall::args)
      .def("__repr__", [](const OpaqueCall& c) {
        return "OpaqueCall(" + c.function + (c.args.is_none() ? "" : ", " + std::string(py::repr(c.args))) + ")";
      });
  m.def(
      "read_torch_file",
      [](const std::string& path) {
        std::unique_ptr<io::TorchFile> file;
        {
          py::gil_scoped_release release;
          file = std::make_unique<io::TorchFile>(path);
        }
        return PickleToPython(*file).convert(file->root());
      },
      py::arg("path"),
      R"(The object a torch.save file holds (zip format or the legacy one), read without Python's unpickler: nothing in
the file is executed. dicts (also OrderedDicts), lists, tuples, sets, numbers, strings, bytes and tensors come back
as themselves; any other call (optimizer or argparse objects...) as an OpaqueCall naming the function and holding its
arguments. Tensors are CPU tensors in the file's dtype; views of one storage share memory, as with torch.load.)");
}

void bind_safetensors(py::module_& m) {
  m.def(
      "read_safetensors",
      [](const std::string& path, bool with_metadata) -> py::object {
        io::Safetensors st;
        {
          py::gil_scoped_release release;
          st = io::read_safetensors(path);
        }
        py::dict tensors = tensor_dict(st.tensors);
        if (!with_metadata) return std::move(tensors);
        py::dict metadata;
        for (const auto& [k, v] : st.metadata) metadata[py::str(k)] = v;
        return py::make_tuple(tensors, metadata);
      },
      py::arg("path"), py::arg("with_metadata") = false,
      R"(The tensors of a safetensors file, {name: tensor} (CPU, the file's dtype), validated (offsets, sizes, dtypes;
errors name the field). with_metadata=True returns (tensors, metadata) with the header's __metadata__ strings.)");
  m.def(
      "write_safetensors",
      [](const std::string& path, const std::map<std::string, torch::Tensor>& tensors,
         const std::map<std::string, std::string>& metadata) {
        py::gil_scoped_release release;
        io::write_safetensors(path, tensors, metadata);
      },
      py::arg("path"), py::arg("tensors"), py::arg("metadata") = std::map<std::string, std::string>{},
      "Writes {name: tensor} (and optional string metadata) as a safetensors file, atomically.");
}

// Images and video: PNG/JPEG in, PNG and MP4 out.
void bind_images(py::module_& m) {
  m.def(
      "read_image",
      [](const std::string& path) {
        py::gil_scoped_release release;
        return io::read_image(path);
      },
      py::arg("path"), "A PNG or JPEG file (told apart by its bytes) as uint8 [H, W, 3] RGB.");
  m.def(
      "write_png",
      [](const std::string& path, const torch::Tensor& image) {
        torch::Tensor hwc = image;
        if (image.is_floating_point()) {
          check_tensor(image, "write_png", "image", {3, -1, -1}, "float [3, H, W] in [0, 1] or uint8 [H, W, 3]");
          hwc = io::to_u8_hwc(image.detach().cpu());
        }
        py::gil_scoped_release release;
        io::write_png(path, hwc.cpu().contiguous());
      },
      py::arg("path"), py::arg("image"), "Writes float [3, H, W] in [0, 1] or uint8 [H, W, 3] as a PNG file.");
  m.def(
      "write_mp4",
      [](const std::string& path, const torch::Tensor& frames, double fps) {
        if (!(fps > 0)) throw py::value_error("write_mp4: fps must be > 0");
        auto hwc = video_frames(frames);
        py::gil_scoped_release release;
        io::write_mp4(path, hwc, fps);
      },
      py::arg("path"), py::arg("frames"), py::arg("fps") = 12.0,
      R"(Writes frames (float [F, 3, H, W] in [0, 1], or uint8 [F, H, W, 3]) as an MP4 (H.264 when FFmpeg has
libx264, else MPEG-4), atomically.)");
}

}  // namespace

void bind_io(py::module_& root) {
  auto m = root.def_submodule("io", "Tensor files without Python's unpickler, images and video.");
  bind_torch_file(m);
  bind_safetensors(m);
  bind_images(m);
}

}  // namespace uplvsm::python
