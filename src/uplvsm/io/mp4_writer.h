// Writing frame sequences as MP4 through FFmpeg's libavformat/libavcodec (libx264 when present, else mpeg4).
// FFmpeg is optional at build time (UPLVSM_WITH_FFMPEG): without it write_mp4 throws and mp4_available() is false.
// Frames are uint8 [H, W, 3] RGB CPU tensors, all the same size; the file is written through a temp file + rename.
#pragma once
#include <torch/torch.h>

#include <string>
#include <vector>

namespace uplvsm::io {

// H.264 (libx264, yuv420p, crf 18) when that encoder exists, else MPEG-4 part 2 at a high fixed quality. Odd widths
// and heights are padded to even by replicating the last column/row. Throws when no encoder is available (or when
// this uplvsm was built without FFmpeg).
void write_mp4(const std::string& path, const std::vector<torch::Tensor>& frames_hwc_u8, double fps);

// Whether write_mp4 can work here (built with FFmpeg, mp4 muxer and one of the encoders present), and which encoder
// it would use ("libx264", "mpeg4" or "" when none).
bool mp4_available();
std::string mp4_encoder_name();

}  // namespace uplvsm::io
