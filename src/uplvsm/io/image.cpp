// JPEG via libjpeg-turbo (setjmp error recovery), PNG via libpng's simplified API, tensor layout conversions.
#include "uplvsm/io/image.h"

#include <cstdio>  // jpeglib.h needs FILE and size_t declared first

#include <jerror.h>
#include <jpeglib.h>
#include <png.h>

#include <atomic>
#include <csetjmp>
#include <cstring>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/io/atomic_file.h"

namespace uplvsm::io {
namespace {

std::atomic<int64_t> g_max_image_pixels{kDefaultMaxImagePixels};

// libjpeg reports fatal errors through error_exit, which must not return: we longjmp back into the (destructor-free)
// function that called libjpeg and turn the message into an exception there.
struct JpegError {
  jpeg_error_mgr mgr;
  jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
  bool truncated;
};

void jpeg_error_exit(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<JpegError*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  longjmp(err->jump, 1);
}

// Warnings (level -1) are silent in libjpeg; a premature end of data is one of them, but a truncated frame is a
// corrupt frame for us (PIL refuses it too), so we remember it.
void jpeg_emit_message(j_common_ptr cinfo, int level) {
  auto* err = reinterpret_cast<JpegError*>(cinfo->err);
  if (level < 0 && cinfo->err->msg_code == JWRN_JPEG_EOF) err->truncated = true;
}

void init_jpeg_error(JpegError* err) {
  jpeg_std_error(&err->mgr);
  err->mgr.error_exit = jpeg_error_exit;
  err->mgr.emit_message = jpeg_emit_message;
  err->message[0] = '\0';
  err->truncated = false;
}

// Header only: fills height/width. Returns false (message in err) on failure. No C++ objects live here, so the
// longjmp is safe.
bool jpeg_read_size_raw(const uint8_t* data, size_t size, JpegError* err, int* height, int* width) {
  jpeg_decompress_struct cinfo;
  cinfo.err = &err->mgr;
  if (setjmp(err->jump)) {
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(&cinfo, TRUE);
  *height = static_cast<int>(cinfo.image_height);
  *width = static_cast<int>(cinfo.image_width);
  jpeg_destroy_decompress(&cinfo);
  return true;
}

// Full decode into `out` (capacity height*width*3 bytes, as returned by jpeg_read_size_raw).
bool jpeg_decode_raw(const uint8_t* data, size_t size, JpegError* err, uint8_t* out, int height, int width) {
  jpeg_decompress_struct cinfo;
  cinfo.err = &err->mgr;
  if (setjmp(err->jump)) {
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(&cinfo, TRUE);
  cinfo.out_color_space = JCS_RGB;
  jpeg_start_decompress(&cinfo);
  if (static_cast<int>(cinfo.output_height) != height || static_cast<int>(cinfo.output_width) != width ||
      cinfo.output_components != 3) {
    std::snprintf(err->message, sizeof(err->message), "unexpected output geometry %ux%ux%d", cinfo.output_height,
                  cinfo.output_width, cinfo.output_components);
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = out + static_cast<size_t>(cinfo.output_scanline) * width * 3;
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  return true;
}

bool jpeg_encode_raw(const uint8_t* pixels, int height, int width, int channels, int quality, JpegError* err,
                     unsigned char** buffer, unsigned long* size) {
  jpeg_compress_struct cinfo;
  cinfo.err = &err->mgr;
  if (setjmp(err->jump)) {
    jpeg_destroy_compress(&cinfo);
    return false;
  }
  jpeg_create_compress(&cinfo);
  jpeg_mem_dest(&cinfo, buffer, size);
  cinfo.image_width = static_cast<JDIMENSION>(width);
  cinfo.image_height = static_cast<JDIMENSION>(height);
  cinfo.input_components = channels;
  cinfo.in_color_space = channels == 3 ? JCS_RGB : JCS_GRAYSCALE;
  jpeg_set_defaults(&cinfo);  // 4:2:0 chroma subsampling for RGB, as PIL's default
  jpeg_set_quality(&cinfo, quality, TRUE);
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < cinfo.image_height) {
    JSAMPROW row = const_cast<uint8_t*>(pixels) + static_cast<size_t>(cinfo.next_scanline) * width * channels;
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  jpeg_destroy_compress(&cinfo);
  return true;
}

void check_u8_image(const torch::Tensor& t, const char* fn, bool allow_gray) {
  bool rgb = t.dim() == 3 && t.size(2) == 3;
  bool gray = allow_gray && t.dim() == 2;
  if (!t.defined() || t.scalar_type() != torch::kUInt8 || !(rgb || gray) || t.size(0) <= 0 || t.size(1) <= 0)
    throw std::runtime_error(fmt::format("{}: expected a uint8 tensor [H,W,3]{}, got {}", fn,
                                         allow_gray ? " or [H,W]" : "",
                                         t.defined() ? c10::str(t.scalar_type(), t.sizes()) : "undefined"));
}

bool is_png(const uint8_t* data, size_t size) {
  static const uint8_t png_magic[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  return data != nullptr && size >= 8 && std::memcmp(data, png_magic, 8) == 0;
}
bool is_jpeg(const uint8_t* data, size_t size) {
  return data != nullptr && size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF;
}

torch::Tensor read_png(const uint8_t* data, size_t size, const std::string& path) {
  png_image image;
  std::memset(&image, 0, sizeof(image));
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, data, size))
    throw std::runtime_error(fmt::format("read_image: {}: not a readable PNG ({})", path, image.message));
  try {
    check_image_pixels(image.height, image.width, path);
  } catch (const std::runtime_error&) {
    png_image_free(&image);
    throw;
  }
  // Keep alpha while decoding and drop it afterwards: asking libpng for RGB would composite onto a background,
  // unlike PIL's convert("RGB").
  bool alpha = (image.format & PNG_FORMAT_FLAG_ALPHA) != 0;
  image.format = alpha ? PNG_FORMAT_RGBA : PNG_FORMAT_RGB;
  int channels = alpha ? 4 : 3;
  auto out =
      torch::empty({static_cast<int64_t>(image.height), static_cast<int64_t>(image.width), channels}, torch::kUInt8);
  if (!png_image_finish_read(&image, nullptr, out.data_ptr<uint8_t>(), 0, nullptr)) {
    std::string message = image.message;
    png_image_free(&image);
    throw std::runtime_error(fmt::format("read_image: {}: corrupt PNG ({})", path, message));
  }
  return alpha ? out.slice(2, 0, 3).contiguous() : out;
}

}  // namespace

void set_max_image_pixels(int64_t pixels) {
  if (pixels < 0)
    throw std::invalid_argument(fmt::format("max image pixels must be >= 0 (0: no limit), got {}", pixels));
  g_max_image_pixels = pixels;
}

int64_t max_image_pixels() { return g_max_image_pixels; }

void check_image_pixels(int64_t height, int64_t width, const std::string& what) {
  if (height <= 0 || width <= 0)
    throw std::runtime_error(fmt::format("{}: image header declares an empty size {}x{}", what, width, height));
  const int64_t limit = max_image_pixels();
  int64_t pixels = 0;
  const bool overflow = __builtin_mul_overflow(height, width, &pixels);
  if (limit > 0 && (overflow || pixels > limit))
    throw std::runtime_error(
        fmt::format("{}: image of {}x{} = {} pixels exceeds the limit of {} pixels (a possible "
                    "decompression bomb; raise it with --max-image-pixels)",
                    what, width, height, overflow ? "too many" : std::to_string(pixels), limit));
}

std::pair<int, int> jpeg_size(const uint8_t* data, size_t size, const std::string& what) {
  if (data == nullptr || size < 4 || data[0] != 0xFF || data[1] != 0xD8)
    throw std::runtime_error(fmt::format("{}: not a JPEG (no FFD8 start marker; {} bytes)", what, size));
  JpegError err;
  init_jpeg_error(&err);
  int height = 0, width = 0;
  if (!jpeg_read_size_raw(data, size, &err, &height, &width))
    throw std::runtime_error(fmt::format("{}: undecodable JPEG header: {}", what, err.message));
  return {height, width};
}

torch::Tensor decode_jpeg(const uint8_t* data, size_t size, const std::string& what) {
  auto [height, width] = jpeg_size(data, size, what);
  check_image_pixels(height, width, what);
  auto out = torch::empty({height, width, 3}, torch::kUInt8);
  JpegError err;
  init_jpeg_error(&err);
  if (!jpeg_decode_raw(data, size, &err, out.data_ptr<uint8_t>(), height, width))
    throw std::runtime_error(fmt::format("{}: undecodable JPEG: {}", what, err.message));
  if (err.truncated) throw std::runtime_error(fmt::format("{}: truncated JPEG (premature end of data)", what));
  return out;
}

std::vector<uint8_t> encode_jpeg(const torch::Tensor& hwc_u8, int quality) {
  check_u8_image(hwc_u8, "encode_jpeg", true);
  if (quality < 1 || quality > 100)
    throw std::runtime_error(fmt::format("encode_jpeg: quality {} not in 1..100", quality));
  auto img = hwc_u8.contiguous();
  int channels = img.dim() == 3 ? 3 : 1;
  JpegError err;
  init_jpeg_error(&err);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  bool ok = jpeg_encode_raw(img.data_ptr<uint8_t>(), static_cast<int>(img.size(0)), static_cast<int>(img.size(1)),
                            channels, quality, &err, &buffer, &size);
  std::vector<uint8_t> bytes;
  if (ok) bytes.assign(buffer, buffer + size);
  std::free(buffer);
  if (!ok) throw std::runtime_error(fmt::format("encode_jpeg: {}", err.message));
  return bytes;
}

std::vector<uint8_t> encode_png(const torch::Tensor& hwc_u8) {
  check_u8_image(hwc_u8, "encode_png", true);
  auto img = hwc_u8.contiguous();
  png_image image;
  std::memset(&image, 0, sizeof(image));
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(img.size(1));
  image.height = static_cast<png_uint_32>(img.size(0));
  image.format = img.dim() == 3 ? PNG_FORMAT_RGB : PNG_FORMAT_GRAY;
  png_alloc_size_t size = 0;
  // First call sizes the buffer, second fills it.
  if (!png_image_write_to_memory(&image, nullptr, &size, 0, img.data_ptr<uint8_t>(), 0, nullptr))
    throw std::runtime_error(fmt::format("encode_png: {}", image.message));
  std::vector<uint8_t> buffer(size);
  if (!png_image_write_to_memory(&image, buffer.data(), &size, 0, img.data_ptr<uint8_t>(), 0, nullptr))
    throw std::runtime_error(fmt::format("encode_png: {}", image.message));
  buffer.resize(size);
  return buffer;
}

void write_png(const std::string& path, const torch::Tensor& hwc_u8) {
  std::vector<uint8_t> bytes;
  try {
    bytes = encode_png(hwc_u8);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("write_png: {}: {}", path, e.what()));
  }
  write_file_atomic(path, bytes.data(), bytes.size());
}

torch::Tensor decode_image(const uint8_t* data, size_t size, const std::string& what) {
  if (is_png(data, size)) return read_png(data, size, what);
  if (is_jpeg(data, size)) return decode_jpeg(data, size, what);
  throw std::runtime_error(fmt::format("{}: neither PNG nor JPEG (unknown magic bytes; {} bytes)", what, size));
}

std::pair<int, int> image_size(const uint8_t* data, size_t size, const std::string& what) {
  if (is_png(data, size)) {
    // IHDR is the first chunk: width and height big-endian at bytes 16..23.
    if (size < 24) throw std::runtime_error(fmt::format("{}: truncated PNG header ({} bytes)", what, size));
    auto be32 = [&](size_t at) {
      return (uint32_t(data[at]) << 24) | (uint32_t(data[at + 1]) << 16) | (uint32_t(data[at + 2]) << 8) |
             uint32_t(data[at + 3]);
    };
    // PNG limits both to 2^31 - 1; larger values are a corrupt header, not a size.
    const uint32_t height = be32(20), width = be32(16);
    if (height > 0x7fffffffu || width > 0x7fffffffu)
      throw std::runtime_error(fmt::format("{}: corrupt PNG header (size {}x{})", what, width, height));
    return {static_cast<int>(height), static_cast<int>(width)};
  }
  return jpeg_size(data, size, what);
}

torch::Tensor read_image(const std::string& path) {
  auto bytes = read_file(path);
  if (!is_png(bytes.data(), bytes.size()) && !is_jpeg(bytes.data(), bytes.size()))
    throw std::runtime_error(fmt::format("read_image: {}: neither PNG nor JPEG (unknown magic bytes)", path));
  return decode_image(bytes.data(), bytes.size(), path);
}

torch::Tensor to_float_chw(const torch::Tensor& hwc_u8) {
  check_u8_image(hwc_u8, "to_float_chw", false);
  return hwc_u8.permute({2, 0, 1}).to(torch::kFloat32).div_(255.0f).contiguous();
}

torch::Tensor to_u8_hwc(const torch::Tensor& chw_float) {
  if (!chw_float.defined() || chw_float.dim() != 3 || chw_float.size(0) != 3 || !chw_float.is_floating_point())
    throw std::runtime_error(
        fmt::format("to_u8_hwc: expected a float tensor [3,H,W], got {}",
                    chw_float.defined() ? c10::str(chw_float.scalar_type(), chw_float.sizes()) : "undefined"));
  auto t = chw_float.detach().to(torch::kCPU, torch::kFloat32).clamp(0.0, 1.0).mul(255.0f).round();
  return t.to(torch::kUInt8).permute({1, 2, 0}).contiguous();
}

}  // namespace uplvsm::io
