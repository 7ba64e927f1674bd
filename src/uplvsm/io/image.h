// Image files: JPEG decode/encode (libjpeg-turbo), PNG read/write (libpng), and conversions between the uint8
// HWC layout of files and the float32 CHW layout of the model.
#pragma once
#include <torch/torch.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace uplvsm::io {

// Decompression-bomb guard: every decode checks the size its header declares against this many pixels before
// allocating, and refuses larger images with an error naming the source, its size and the limit. The default is
// Pillow's DecompressionBombError threshold (2 x MAX_IMAGE_PIXELS = 178956970); 0 means no limit. Process-wide
// (`uplvsm --max-image-pixels N` sets it); thread-safe.
inline constexpr int64_t kDefaultMaxImagePixels = 178956970;
void set_max_image_pixels(int64_t pixels);
int64_t max_image_pixels();
// Throws when height x width is not a positive size within max_image_pixels(); `what` names the image.
void check_image_pixels(int64_t height, int64_t width, const std::string& what);

// Decodes a complete JPEG file held in memory to uint8 [H,W,3] RGB (grayscale JPEGs are expanded to RGB). Uses
// libjpeg's defaults (integer slow DCT, fancy upsampling), as PIL and OpenCV do. `what` names the source (file,
// scene/frame) in error messages; garbage or truncated data throws std::runtime_error.
torch::Tensor decode_jpeg(const uint8_t* data, size_t size, const std::string& what);

// Reads only the JPEG header: {height, width}. Cheap; used to check frame shapes before decoding.
std::pair<int, int> jpeg_size(const uint8_t* data, size_t size, const std::string& what);

// PNG or JPEG bytes (told apart by their magic bytes, as PIL does; pixelSplat readers open chunk images with
// PIL, so a chunk may carry lossless PNG frames, e.g. converted from the LVSM layout): decode, or read the size.
torch::Tensor decode_image(const uint8_t* data, size_t size, const std::string& what);
std::pair<int, int> image_size(const uint8_t* data, size_t size, const std::string& what);

// Encodes uint8 [H,W,3] RGB (or [H,W] gray) as a baseline JPEG (4:2:0 for RGB) of the given quality (1..100).
std::vector<uint8_t> encode_jpeg(const torch::Tensor& hwc_u8, int quality = 90);

// uint8 RGB [H,W,3] or gray [H,W] -> PNG file bytes.
std::vector<uint8_t> encode_png(const torch::Tensor& hwc_u8);

// Writes uint8 RGB [H,W,3] or gray [H,W] as PNG, atomically (temporary file in the same folder, then rename).
void write_png(const std::string& path, const torch::Tensor& hwc_u8);

// Reads a PNG or JPEG file (detected by its magic bytes, not its name) as uint8 [H,W,3] RGB. Gray is expanded;
// an alpha channel is dropped (as PIL's convert("RGB") does).
torch::Tensor read_image(const std::string& path);

// uint8 [H,W,3] -> float32 [3,H,W] in [0,1] (value / 255).
torch::Tensor to_float_chw(const torch::Tensor& hwc_u8);

// float [3,H,W] -> uint8 [H,W,3]: clamp to [0,1], * 255, round to nearest.
torch::Tensor to_u8_hwc(const torch::Tensor& chw_float);

}  // namespace uplvsm::io
