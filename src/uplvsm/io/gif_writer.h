// Writing frame sequences as GIF animations with an own GIF89a encoder: a global median-cut palette, LZW, optional
// ordered dithering and looping. Frames are uint8 [H, W, 3] RGB CPU tensors, all the same size; the file is
// written through a temp file + rename.
#pragma once
#include <torch/torch.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace uplvsm::io {

// Delay per frame is round(100 / fps) centiseconds (at least 1). `loop` adds the NETSCAPE2.0 infinite-loop block.
// `dither` applies 4x4 ordered dithering when the frames have more than 256 colours (never otherwise).
void write_gif(const std::string& path, const std::vector<torch::Tensor>& frames_hwc_u8, double fps, bool loop = true,
               bool dither = true);

// The GIF palette logic, exposed for tests and for other indexed-colour outputs: a palette of at most 256 colours
// for the given frames (exact when they hold <= 256 distinct colours, median cut otherwise).
std::vector<std::array<uint8_t, 3>> gif_palette(const std::vector<torch::Tensor>& frames_hwc_u8);

}  // namespace uplvsm::io
