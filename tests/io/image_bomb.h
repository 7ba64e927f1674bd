// Decompression-bomb test images: small real PNG/JPEG files whose headers are rewritten to declare a huge size. Their
// pixel data still belongs to the small image, so a decoder that did not refuse them from the header would fail
// with a corrupt-data error instead of the pixel-limit error the tests expect.
#pragma once
#include <zlib.h>

#include <cstdint>
#include <vector>

#include "uplvsm/io/image.h"

namespace uplvsm::test {

inline std::vector<uint8_t> small_image_bytes(bool png) {
  auto img = torch::arange(16 * 8 * 3).remainder(251).to(torch::kUInt8).view({8, 16, 3}).contiguous();
  return png ? io::encode_png(img) : io::encode_jpeg(img, 90);
}

inline void put_be(std::vector<uint8_t>& bytes, size_t at, uint32_t value, int size) {
  for (int i = 0; i < size; ++i) bytes[at + i] = uint8_t(value >> (8 * (size - 1 - i)));
}

// IHDR is the first chunk: width and height at bytes 16..23, its CRC (over type and data) at 29..32.
inline std::vector<uint8_t> png_declaring(uint32_t width, uint32_t height) {
  auto bytes = small_image_bytes(true);
  put_be(bytes, 16, width, 4);
  put_be(bytes, 20, height, 4);
  put_be(bytes, 29, uint32_t(crc32(0, bytes.data() + 12, 17)), 4);
  return bytes;
}

// The baseline SOF0 segment (FFC0, length, precision) holds height then width as 16-bit values.
inline std::vector<uint8_t> jpeg_declaring(uint16_t width, uint16_t height) {
  auto bytes = small_image_bytes(false);
  for (size_t i = 2; i + 9 < bytes.size(); ++i)
    if (bytes[i] == 0xFF && bytes[i + 1] == 0xC0) {
      put_be(bytes, i + 5, height, 2);
      put_be(bytes, i + 7, width, 2);
      break;
    }
  return bytes;
}

}  // namespace uplvsm::test
