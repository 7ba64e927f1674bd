// Writing frame sequences as animations: an own GIF89a encoder (global median-cut palette, LZW, optional ordered
// dithering, looping) and MP4 through FFmpeg's libavformat/libavcodec (libx264 when present, else mpeg4).
// Frames are uint8 [H, W, 3] RGB CPU tensors, all the same size. Both writers go through a temp file + rename.
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

// H.264 (libx264, yuv420p, crf 18) when that encoder exists, else MPEG-4 part 2 at a high fixed quality. Odd widths
// and heights are padded to even by replicating the last column/row. Throws when no encoder is available.
void write_mp4(const std::string& path, const std::vector<torch::Tensor>& frames_hwc_u8, double fps);

// Whether write_mp4 can work here (mp4 muxer and one of the encoders present), and which encoder it would use
// ("libx264", "mpeg4" or "" when none).
bool mp4_available();
std::string mp4_encoder_name();

// The GIF palette logic, exposed for tests and for other indexed-colour outputs: a palette of at most 256 colours
// for the given frames (exact when they hold <= 256 distinct colours, median cut otherwise).
std::vector<std::array<uint8_t, 3>> gif_palette(const std::vector<torch::Tensor>& frames_hwc_u8);

}  // namespace uplvsm::io
