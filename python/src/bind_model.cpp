// uplvsm.load and uplvsm.Model: the model as torch tensors in and out. Every method releases the GIL while the model
// runs (several Python threads may render with one model at once) and respects torch.no_grad() / grad mode.
#include <memory>
#include <optional>

#include "binding_util.h"
#include "model_adapter.h"
#include "uplvsm/core/config.h"

namespace uplvsm::python {

namespace {

using Model = ModelAdapter;

torch::Tensor optional_tensor(const std::optional<torch::Tensor>& t) { return t ? *t : torch::Tensor(); }

model::Views batch_views(const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                         const std::optional<torch::Tensor>& c2w, const char* where, const std::string& which) {
  check_tensor(images, where, which + "_images", {-1, -1, 3, -1, -1}, "[b, v, 3, H, W]");
  check_tensor(fxfycxcy, where, which + "_fxfycxcy", {images.size(0), images.size(1), 4},
               "[b, v, 4] (" + c10::str(images.sizes().slice(0, 2)) + " views)");
  if (c2w) check_tensor(*c2w, where, which + "_c2w", {images.size(0), images.size(1), 4, 4}, "[b, v, 4, 4]");
  return {images, fxfycxcy, optional_tensor(c2w)};
}

void check_pair_views(const torch::Tensor& images, const torch::Tensor& fxfycxcy, const char* where) {
  check_tensor(images, where, "images", {-1, 3, -1, -1}, "[v, 3, H, W]");
  check_tensor(fxfycxcy, where, "fxfycxcy", {images.size(0), 4}, "[v, 4] (one row per image)");
}

std::shared_ptr<Model> load(const std::string& path, const py::object& device, const py::object& config) {
  const auto dev = to_device(device);
  std::optional<Config> hint;
  if (!config.is_none()) hint = to_config(config);
  py::gil_scoped_release release;
  return std::make_shared<Model>(path, dev, hint ? &*hint : nullptr);
}

std::shared_ptr<Model> init(const py::object& config, const py::object& device, uint64_t seed) {
  const auto dev = to_device(device);
  const Config c = to_config(config);
  py::gil_scoped_release release;
  return std::make_shared<Model>(c, dev, seed);
}

py::dict forward(Model& m, const torch::Tensor& input_images, const torch::Tensor& input_fxfycxcy,
                 const torch::Tensor& target_images, const torch::Tensor& target_fxfycxcy,
                 const std::string& target_poses, const std::optional<torch::Tensor>& input_c2w,
                 const std::optional<torch::Tensor>& target_c2w, const std::string& amp) {
  auto inputs = batch_views(input_images, input_fxfycxcy, input_c2w, "forward", "input");
  auto targets = batch_views(target_images, target_fxfycxcy, target_c2w, "forward", "target");
  if (target_images.size(0) != input_images.size(0))
    throw py::value_error("forward: input_images and target_images differ in batch size (" +
                          std::to_string(input_images.size(0)) + " vs " + std::to_string(target_images.size(0)) + ")");
  ForwardResult r;
  {
    py::gil_scoped_release release;
    r = m.forward(inputs, targets, target_poses, amp);
  }
  py::dict out;
  out["render"] = r.render;
  out["poses"] = r.poses.defined() ? py::cast(r.poses) : py::none();
  return out;
}

using ModelClass = py::class_<Model, std::shared_ptr<Model>>;

// What the model is: its config, device, variant, name, size and weights.
void bind_model_properties(ModelClass& c) {
  c.def_property_readonly(
       "config", [](const Model& s) { return to_python(config_to_json(s.config())); },
       "The full config (model, training, eval, dataset sections) as a dict.")
      .def_property_readonly("device", &Model::device)
      .def_property_readonly(
          "variant", [](const Model& s) { return to_string(s.config().model.variant); },
          "\"uplvsm\", \"ptlvsm\" or \"lvsm\".")
      .def_property_readonly("name", &Model::name,
                             "The paper's name of the model: \"UP-LVSM\", \"PT-LVSM\" or \"LVSM\".")
      .def("parameter_count", &Model::parameter_count, "Number of parameters.")
      .def(
          "state_dict", [](const Model& s) { return tensor_dict(s.state_dict()); },
          "Parameters and buffers by checkpoint name, sharing the model's memory (an in-place change is the "
          "model's).");
}

// The three stages of UP-LVSM on their own: encode the scene, estimate target poses, render from latent poses.
void bind_model_stages(ModelClass& c) {
  c.def(
       "encode_scene",
       [](Model& s, const torch::Tensor& images, const torch::Tensor& fxfycxcy, const std::string& amp) {
         batch_views(images, fxfycxcy, std::nullopt, "encode_scene", "input");
         py::gil_scoped_release release;
         return s.encode_scene(images, fxfycxcy, amp);
       },
       py::arg("input_images"), py::arg("input_fxfycxcy"), py::arg("amp") = "none",
       "Scene latents [b, L, d] from unposed input views [b, v, 3, H, W] and their intrinsics [b, v, 4]. UP-LVSM "
       "only (ValueError for a posed model).")
      .def(
          "estimate_poses",
          [](Model& s, const torch::Tensor& images, const torch::Tensor& latents, const std::string& amp) {
            check_tensor(images, "estimate_poses", "target_images", {-1, -1, 3, -1, -1}, "[b, v, 3, H, W]");
            check_tensor(latents, "estimate_poses", "scene_latents", {images.size(0), -1, -1}, "[b, L, d]");
            py::gil_scoped_release release;
            return s.estimate_poses(images, latents, amp);
          },
          py::arg("target_images"), py::arg("scene_latents"), py::arg("amp") = "none",
          "Latent poses [b, v, 7] of target images given the scene latents (the Latent Plücker Learner). UP-LVSM "
          "only.")
      .def(
          "render_views",
          [](Model& s, const torch::Tensor& latents, const torch::Tensor& poses, const torch::Tensor& fxfycxcy,
             int64_t height, int64_t width, const std::string& amp) {
            check_tensor(latents, "render_views", "scene_latents", {-1, -1, -1}, "[b, L, d]");
            check_tensor(poses, "render_views", "poses", {latents.size(0), -1, 7}, "[b, v, 7]");
            check_tensor(fxfycxcy, "render_views", "fxfycxcy", {latents.size(0), poses.size(1), 4}, "[b, v, 4]");
            if (height <= 0 || width <= 0) throw py::value_error("render_views: height and width must be > 0");
            py::gil_scoped_release release;
            return s.render_views(latents, poses, fxfycxcy, height, width, amp);
          },
          py::arg("scene_latents"), py::arg("poses"), py::arg("fxfycxcy"), py::arg("height"), py::arg("width"),
          py::arg("amp") = "none",
          "Renders [b, v, 3, H, W] from scene latents, latent poses and intrinsics. UP-LVSM only.");
}

// The evaluation forward, also as __call__.
void bind_model_forward(ModelClass& c) {
  c.def("forward", &forward, py::arg("input_images"), py::arg("input_fxfycxcy"), py::arg("target_images"),
        py::arg("target_fxfycxcy"), py::arg("target_poses") = "auto", py::arg("input_c2w") = py::none(),
        py::arg("target_c2w") = py::none(), py::arg("amp") = "none",
        R"(The evaluation forward: renders the targets [b, v_t, 3, H, W] from the inputs. target_poses: "auto" (the
model's own protocol: the estimator reads the target images for UP-LVSM, dataset cameras for the posed variants),
"estimator", "mapper" or "dataset" (the last two need input_c2w and target_c2w [b, v, 4, 4]). Returns
{"render": tensor, "poses": latent poses [b, v_t, 7] or None for the posed variants}.)")
      .def("__call__", &forward, py::arg("input_images"), py::arg("input_fxfycxcy"), py::arg("target_images"),
           py::arg("target_fxfycxcy"), py::arg("target_poses") = "auto", py::arg("input_c2w") = py::none(),
           py::arg("target_c2w") = py::none(), py::arg("amp") = "none", "Same as forward().");
}

// Videos: between two unposed photos, or along a real camera path.
void bind_model_videos(ModelClass& c) {
  c.def(
       "render_interpolation",
       [](Model& s, const torch::Tensor& images, const torch::Tensor& fxfycxcy, int64_t num_frames, int64_t chunk,
          const std::string& amp) {
         check_pair_views(images, fxfycxcy, "render_interpolation");
         if (images.size(0) != 2) throw py::value_error("render_interpolation: images must be two views [2, 3, H, W]");
         if (num_frames < 2 || chunk < 1)
           throw py::value_error("render_interpolation: num_frames must be >= 2 and chunk >= 1");
         render::InterpolationVideo v;
         {
           py::gil_scoped_release release;
           v = s.render_interpolation(images, fxfycxcy, num_frames, chunk, amp);
         }
         py::dict out;
         out["frames"] = v.frames;
         out["poses"] = v.poses;
         out["key_poses"] = v.key_poses;
         return out;
       },
       py::arg("images"), py::arg("fxfycxcy"), py::arg("num_frames") = 24, py::arg("chunk") = 4,
       py::arg("amp") = "none",
       R"(A video between two unposed photos (images [2, 3, H, W], fxfycxcy [2, 4]): the estimator's latent poses of
the two inputs, interpolated (slerp + linear) over num_frames frames, rendered chunk frames at a time, without
gradients; UP-LVSM only. Returns {"frames": [F, 3, H, W] CPU, "poses": [F, 7], "key_poses": [2, 7]}.)")
      .def(
          "render_camera_path",
          [](Model& s, const torch::Tensor& images, const torch::Tensor& fxfycxcy, const torch::Tensor& poses,
             const torch::Tensor& path_fxfycxcy, const std::optional<torch::Tensor>& c2w, int64_t chunk,
             const std::string& amp) {
            check_pair_views(images, fxfycxcy, "render_camera_path");
            check_tensor(poses, "render_camera_path", "poses", {-1, 7}, "[F, 7]");
            check_tensor(path_fxfycxcy, "render_camera_path", "path_fxfycxcy", {poses.size(0), 4}, "[F, 4]");
            if (c2w) check_tensor(*c2w, "render_camera_path", "c2w", {images.size(0), 4, 4}, "[v, 4, 4]");
            if (chunk < 1) throw py::value_error("render_camera_path: chunk must be >= 1");
            py::gil_scoped_release release;
            return s.render_camera_path({images, fxfycxcy, optional_tensor(c2w), {}}, poses, path_fxfycxcy, chunk, amp);
          },
          py::arg("images"), py::arg("fxfycxcy"), py::arg("poses"), py::arg("path_fxfycxcy"),
          py::arg("c2w") = py::none(), py::arg("chunk") = 4, py::arg("amp") = "none",
          R"(Frames [F, 3, H, W] (CPU) at real cameras: poses [F, 7] in camera-control units (first input view at the
origin, translations in input baselines, OpenCV axes), path_fxfycxcy [F, 4] pixels. Needs a camera mapper
(`uplvsm train --stage mapper`) for UP-LVSM, or a posed variant with the inputs' c2w [v, 4, 4].)");
}

// uplvsm.init and uplvsm.load, registered after the class so their signatures name uplvsm.Model.
void bind_model_constructors(py::module_& m) {
  m.def("init", &init, py::arg("config"), py::arg("device") = "cpu", py::arg("seed") = 0,
        R"(A freshly initialised model of a config (a dict or a path to a config JSON, e.g. configs/paper_x224.json):
the model's own initialisation drawn after torch.manual_seed(seed) (the global generator is reseeded), in eval mode.
For benchmarks and for training from scratch in Python.)");
  m.def("load", &load, py::arg("path"), py::arg("device") = "cpu", py::arg("config") = py::none(),
        R"(A ready model from any weight file: a uplvsm checkpoint (file, checkpoints dir or run dir; its own config),
the authors' UP-LVSM / PT-LVSM .pt/.pth/.safetensors (dimensions inferred from the tensors, 224 px unless `config`
says otherwise), loaded strictly (missing, unexpected and mis-shaped keys are listed by name). device: "cpu",
"cuda", "cuda:N", "auto" or a torch.device. config: None, a dict or a path to a config JSON (its model section
applies to the authors' files only).)");
}

}  // namespace

void bind_model(py::module_& m) {
  ModelClass c(m, "Model", R"(A UP-LVSM (or a posed PT-LVSM / LVSM) model, ready for
inference on its device. Get one with uplvsm.load(). Images are float [0, 1] tensors [b, v, 3, H, W], intrinsics
fxfycxcy in pixels [b, v, 4], poses the model's 7-D latent poses (tx, ty, tz, qx, qy, qz, qw). Inputs are moved to
the model's device (no copy when they are already there). Gradients flow unless you call under torch.no_grad().
amp="bf16" runs matmuls in bfloat16 autocast, as the CLI's --amp bf16.)");
  bind_model_properties(c);
  bind_model_stages(c);
  bind_model_forward(c);
  bind_model_videos(c);
  c.def("__repr__", [](const Model& s) {
    return "uplvsm.Model(variant='" + to_string(s.config().model.variant) +
           "', parameters=" + std::to_string(s.parameter_count()) + ", device='" + s.device().str() + "')";
  });
  bind_model_constructors(m);
}

}  // namespace uplvsm::python
