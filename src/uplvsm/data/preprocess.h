// The official UP-LVSM frame preprocessing (official-uplvsm.md §1): PIL-exact LANCZOS resize to image_size rows,
// centred square crop, /255, intrinsics rescaled and shifted; plus the 18-float camera row conversions.
#pragma once
#include <torch/torch.h>

#include <string>
#include <utility>
#include <vector>

#include "uplvsm/core/config.h"
#include "uplvsm/data/scene.h"

namespace uplvsm::data {

struct PreprocessOptions {
  int image_size = 224;     // output rows (Hr); also the square side when square_crop
  int patch_size = 14;      // the resized width is rounded to a multiple of this
  bool square_crop = true;  // centred crop of side min(Hr, Wr)
};

// The preprocessing a model of `config` expects: its image and patch size, the dataset's square_crop.
PreprocessOptions preprocess_options(const Config& config);
// The same with a square crop whatever the dataset says: what render's videos and the viewer show.
PreprocessOptions square_preprocess_options(const Config& config);

// Decoded frames (uint8 [H0,W0,3] each, typically all the same size) and their camera rows [V,18] -> SceneViews.
// `frames` of the result is 0..V-1 (callers that know the scene's frame numbers overwrite it). `what` names the
// source in errors (NaN camera, wrong shapes, frames whose output size differs).
SceneViews preprocess(const std::vector<torch::Tensor>& hwc_u8_frames, const torch::Tensor& cameras18,
                      const PreprocessOptions& opt, const std::string& what = "preprocess");

// A user's photo (uint8 [H,W,3]) as one view: a pinhole camera with the principal point at the centre, square
// pixels and the given horizontal field of view, identity pose (unused by the unposed model).
SceneViews preprocess_photo(const torch::Tensor& hwc_u8, double fov_deg, const PreprocessOptions& opt,
                            const std::string& what);

// Wr = round(int(Hr / H0 * W0) / patch) * patch, with Python's round (half to even), as the official code.
int resized_width(int height, int width, int image_size, int patch_size);
// The [rows, columns] a height x width frame preprocesses to: [Hr, Wr], or the square crop's side twice.
std::pair<int, int> preprocessed_size(int height, int width, const PreprocessOptions& opt);

// PIL's Image.resize((out_w, out_h), Image.LANCZOS) on a uint8 [H,W,3] image, bit for bit (Pillow's
// ImagingResample: separable, horizontal pass then vertical, support scaled by the downscale factor, coefficients
// normalised then quantised to 22 fractional bits, round-half-up accumulation, clamped to 0..255).
torch::Tensor resize_lanczos_pil(const torch::Tensor& hwc_u8, int out_w, int out_h);

// Validates camera rows: a float tensor [N,18] with finite values. `what` names the scene; the first bad frame
// is named in the error.
void check_cameras(const torch::Tensor& cameras18, const std::string& what);

// c2w float32 [N,4,4] = inverse of the padded world-to-camera rows, inverted in float64 then cast.
torch::Tensor cameras_to_c2w(const torch::Tensor& cameras18, const std::string& what);

// Pixel intrinsics float32 [N,4] (fx, fy, cx, cy) of an image of the given size: normalised values times W or H.
torch::Tensor cameras_to_fxfycxcy(const torch::Tensor& cameras18, int width, int height);

// Builds camera rows float32 [N,18] from pixel intrinsics [N,4] of a width x height image and w2c [N,3,4] or
// [N,4,4] (the inverse of the conversions above; used by dataset writers).
torch::Tensor make_cameras18(const torch::Tensor& fxfycxcy_px, const torch::Tensor& w2c, int width, int height);

}  // namespace uplvsm::data
