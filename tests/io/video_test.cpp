// GIF and MP4 writers: byte structure, an exact GIF decode with a small reference LZW decoder, and an MP4 reopened
// and decoded with libavformat/libavcodec (a build without FFmpeg skips those and checks write_mp4's error).
#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/video.h"

#ifdef UPLVSM_WITH_FFMPEG
extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libswscale/swscale.h>
}
#endif

namespace uplvsm::io {
namespace {

using test::remove_tree;
using test::temp_dir;

// n frames h x w of a moving gradient; `few_colours` quantises it to 160 distinct colours (an exact GIF palette).
std::vector<torch::Tensor> gradient_frames(int n = 12, int h = 36, int w = 64, bool few_colours = false) {
  std::vector<torch::Tensor> frames;
  auto y = torch::arange(h, torch::kInt32).view({h, 1}).expand({h, w});
  auto x = torch::arange(w, torch::kInt32).view({1, w}).expand({h, w});
  for (int t = 0; t < n; ++t) {
    torch::Tensor r, g, b;
    if (few_colours) {
      r = torch::div(x, 8, "floor") * 32, g = torch::div(y, 8, "floor") * 60;
      b = torch::full_like(x, (t % 4) * 60);
    } else {
      r = (x * 255 / (w - 1) + t * 6).clamp(0, 255), g = y * 255 / (h - 1), b = ((x + y + t * 3) * 2).clamp(0, 255);
    }
    frames.push_back(torch::stack({r, g, b}, 2).to(torch::kUInt8).contiguous());
  }
  return frames;
}

// ---- a minimal GIF decoder: global palette + LZW, enough for what write_gif produces ----
struct DecodedGif {
  int width = 0, height = 0;
  bool loops = false;
  std::vector<int> delays;
  std::vector<torch::Tensor> frames;  // RGB through the palette
};

std::vector<uint8_t> lzw_decode(const std::vector<uint8_t>& data, int min_size, size_t n_pixels) {
  const int clear = 1 << min_size, eoi = clear + 1;
  std::vector<std::vector<uint8_t>> dict;
  auto reset = [&] {
    dict.assign(size_t(eoi + 1), {});
    for (int i = 0; i < clear; ++i) dict[size_t(i)] = {uint8_t(i)};
  };
  reset();
  int size = min_size + 1, prev = -1;
  size_t bitpos = 0;
  std::vector<uint8_t> out;
  while (true) {
    if (bitpos + size_t(size) > data.size() * 8) throw std::runtime_error("LZW data ended without EOI");
    int code = 0;
    for (int i = 0; i < size; ++i, ++bitpos) code |= ((data[bitpos / 8] >> (bitpos % 8)) & 1) << i;
    if (code == clear) {
      reset();
      size = min_size + 1, prev = -1;
      continue;
    }
    if (code == eoi) break;
    std::vector<uint8_t> entry;
    if (code < int(dict.size())) {
      entry = dict[size_t(code)];
    } else if (code == int(dict.size()) && prev >= 0) {
      entry = dict[size_t(prev)];
      entry.push_back(entry[0]);
    } else {
      throw std::runtime_error("bad LZW code " + std::to_string(code));
    }
    out.insert(out.end(), entry.begin(), entry.end());
    if (prev >= 0 && dict.size() < 4096) {
      auto e = dict[size_t(prev)];
      e.push_back(entry[0]);
      dict.push_back(e);
      if (dict.size() == (size_t(1) << size) && size < 12) ++size;
    }
    prev = code;
  }
  EXPECT_EQ(out.size(), n_pixels);
  return out;
}

DecodedGif decode_gif(const std::vector<uint8_t>& b) {
  DecodedGif g;
  EXPECT_EQ(std::string(b.begin(), b.begin() + 6), "GIF89a");
  EXPECT_EQ(b.back(), 0x3B);
  auto u16 = [&](size_t i) { return int(b[i]) | (int(b[i + 1]) << 8); };
  g.width = u16(6), g.height = u16(8);
  EXPECT_EQ(b[10] & 0x80, 0x80);  // global colour table
  int table = 1 << ((b[10] & 7) + 1);
  size_t pos = 13;
  std::vector<uint8_t> palette(b.begin() + 13, b.begin() + 13 + 3 * table);
  pos += size_t(3 * table);
  auto read_blocks = [&](size_t& p) {
    std::vector<uint8_t> data;
    while (b[p] != 0) {
      data.insert(data.end(), b.begin() + p + 1, b.begin() + p + 1 + b[p]);
      p += b[p] + 1;
    }
    ++p;
    return data;
  };
  while (b.at(pos) != 0x3B) {
    if (b[pos] == 0x21) {  // extension
      int label = b[pos + 1];
      pos += 2;
      size_t body = pos;
      auto data = read_blocks(pos);
      if (label == 0xF9) g.delays.push_back(int(data[1]) | (int(data[2]) << 8));
      if (label == 0xFF && std::string(b.begin() + body + 1, b.begin() + body + 12) == "NETSCAPE2.0") g.loops = true;
    } else if (b[pos] == 0x2C) {  // image
      int w = u16(pos + 5), h = u16(pos + 7);
      EXPECT_EQ(b[pos + 9] & 0x80, 0);  // no local table
      int min_size = b[pos + 10];
      pos += 11;
      auto idx = lzw_decode(read_blocks(pos), min_size, size_t(w * h));
      auto img = torch::empty({h, w, 3}, torch::kUInt8);
      for (size_t i = 0; i < idx.size() && i < size_t(w * h); ++i)
        for (int c = 0; c < 3; ++c) img.data_ptr<uint8_t>()[3 * i + size_t(c)] = palette[3 * idx[i] + size_t(c)];
      g.frames.push_back(img);
    } else {
      ADD_FAILURE() << "unexpected GIF block " << int(b[pos]) << " at " << pos;
      break;
    }
  }
  return g;
}

TEST(Gif, ExactRoundTripWithFewColours) {
  auto dir = temp_dir("gif_exact");
  std::string path = (dir / "anim.gif").string();
  auto frames = gradient_frames(12, 36, 64, true);
  write_gif(path, frames, 10.0);
  auto g = decode_gif(read_file(path));
  EXPECT_EQ(g.width, 64);
  EXPECT_EQ(g.height, 36);
  EXPECT_TRUE(g.loops);
  ASSERT_EQ(g.frames.size(), 12u);
  EXPECT_EQ(g.delays, std::vector<int>(12, 10));
  for (size_t i = 0; i < frames.size(); ++i) EXPECT_TRUE(torch::equal(g.frames[i], frames[i])) << "frame " << i;
  remove_tree(dir);
}

TEST(Gif, RandomIndicesExerciseEveryCodeSize) {
  // Random pixels over 256 colours fill the LZW table repeatedly (clear codes, 12-bit codes); odd sizes and
  // varying colour counts move where the code-size changes fall relative to the end of the data.
  auto dir = temp_dir("gif_random");
  torch::manual_seed(3);
  auto palette = torch::randperm(1 << 24, torch::kInt64).narrow(0, 0, 256);
  for (auto [h, w, ncol] : std::vector<std::tuple<int, int, int>>{
           {1, 1, 1}, {1, 2, 2}, {3, 7, 2}, {17, 31, 5}, {61, 67, 256}, {200, 211, 256}, {150, 97, 16}}) {
    for (int rep = 0; rep < 3; ++rep) {
      auto idx = torch::randint(0, ncol, {h, w}, torch::kInt64);
      auto col = palette.index({idx});
      auto img = torch::stack({torch::div(col, 65536, "floor"), torch::div(col, 256, "floor") % 256, col % 256}, 2)
                     .to(torch::kUInt8)
                     .contiguous();
      std::string path = (dir / "r.gif").string();
      write_gif(path, {img}, 25.0, false);
      auto g = decode_gif(read_file(path));
      EXPECT_FALSE(g.loops);
      EXPECT_EQ(g.delays, std::vector<int>{4});
      ASSERT_EQ(g.frames.size(), 1u);
      EXPECT_TRUE(torch::equal(g.frames[0], img)) << h << "x" << w << " colours " << ncol;
    }
  }
  remove_tree(dir);
}

TEST(Gif, ManyColoursAreQuantisedClosely) {
  auto dir = temp_dir("gif_lossy");
  std::string path = (dir / "smooth.gif").string();
  auto frames = gradient_frames(6, 48, 80, false);
  auto palette = gif_palette(frames);
  EXPECT_EQ(palette.size(), 256u);
  for (bool dither : {false, true}) {
    write_gif(path, frames, 7.0, true, dither);
    auto g = decode_gif(read_file(path));
    ASSERT_EQ(g.frames.size(), frames.size());
    EXPECT_EQ(g.delays[0], 14);  // round(100 / 7)
    for (size_t i = 0; i < frames.size(); ++i) {
      double err = (g.frames[i].to(torch::kFloat32) - frames[i].to(torch::kFloat32)).abs().mean().item<double>();
      EXPECT_LT(err, dither ? 8.0 : 5.0) << "frame " << i;
    }
  }
  remove_tree(dir);
}

TEST(Gif, RejectsBadFrames) {
  auto dir = temp_dir("gif_bad");
  std::string path = (dir / "bad.gif").string();
  EXPECT_THROW(write_gif(path, {}, 10), std::runtime_error);
  auto frames = gradient_frames(3);
  frames.push_back(torch::zeros({10, 10, 3}, torch::kUInt8));
  try {
    write_gif(path, frames, 10);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("frame 3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(write_gif(path, {torch::zeros({4, 4, 3})}, 10), std::runtime_error);  // float
  EXPECT_THROW(write_gif(path, {torch::zeros({4, 4}, torch::kUInt8)}, 10), std::runtime_error);
  EXPECT_THROW(write_gif(path, gradient_frames(2), 0.0), std::runtime_error);
  EXPECT_FALSE(std::filesystem::exists(path));
  remove_tree(dir);
}

// ---- MP4 ----

struct DecodedVideo {
  int streams = 0, width = 0, height = 0, frames = 0;
  torch::Tensor first;  // RGB
};

#ifdef UPLVSM_WITH_FFMPEG
DecodedVideo decode_mp4(const std::string& path) {
  DecodedVideo out;
  AVFormatContext* fmt = nullptr;
  if (avformat_open_input(&fmt, path.c_str(), nullptr, nullptr) < 0) throw std::runtime_error("cannot open " + path);
  avformat_find_stream_info(fmt, nullptr);
  out.streams = int(fmt->nb_streams);
  AVCodecParameters* par = fmt->streams[0]->codecpar;
  out.width = par->width, out.height = par->height;
  const AVCodec* dec = avcodec_find_decoder(par->codec_id);
  AVCodecContext* cc = avcodec_alloc_context3(dec);
  avcodec_parameters_to_context(cc, par);
  avcodec_open2(cc, dec, nullptr);
  AVPacket* pkt = av_packet_alloc();
  AVFrame* frame = av_frame_alloc();
  auto receive = [&] {
    while (avcodec_receive_frame(cc, frame) == 0) {
      if (out.frames++ == 0) {
        out.first = torch::empty({frame->height, frame->width, 3}, torch::kUInt8);
        SwsContext* sws =
            sws_getContext(frame->width, frame->height, AVPixelFormat(frame->format), frame->width, frame->height,
                           AV_PIX_FMT_RGB24, SWS_BILINEAR | SWS_ACCURATE_RND, nullptr, nullptr, nullptr);
        uint8_t* dst[1] = {out.first.data_ptr<uint8_t>()};
        int stride[1] = {3 * frame->width};
        sws_scale(sws, frame->data, frame->linesize, 0, frame->height, dst, stride);
        sws_freeContext(sws);
      }
    }
  };
  while (av_read_frame(fmt, pkt) >= 0) {
    if (pkt->stream_index == 0) avcodec_send_packet(cc, pkt);
    av_packet_unref(pkt);
    receive();
  }
  avcodec_send_packet(cc, nullptr);
  receive();
  av_frame_free(&frame);
  av_packet_free(&pkt);
  avcodec_free_context(&cc);
  avformat_close_input(&fmt);
  return out;
}
#else
// Nothing here decodes MP4 without FFmpeg; the tests that would call this skip first (mp4_available() is false).
DecodedVideo decode_mp4(const std::string& path) {
  throw std::runtime_error("built without FFmpeg: cannot decode " + path);
}
#endif  // UPLVSM_WITH_FFMPEG

double psnr(const torch::Tensor& a, const torch::Tensor& b) {
  double mse = (a.to(torch::kFloat64) - b.to(torch::kFloat64)).pow(2).mean().item<double>();
  return 10 * std::log10(255.0 * 255.0 / std::max(mse, 1e-12));
}

TEST(Mp4, WritesDecodableVideo) {
  if (!mp4_available()) GTEST_SKIP() << "no MP4 output here (no encoder in this FFmpeg, or built without FFmpeg)";
  std::cout << "mp4 encoder: " << mp4_encoder_name() << "\n";
  auto dir = temp_dir("mp4");
  std::string path = (dir / "anim.mp4").string();
  auto frames = gradient_frames(12, 36, 64, false);
  write_mp4(path, frames, 12.0);
  auto v = decode_mp4(path);
  EXPECT_EQ(v.streams, 1);
  EXPECT_EQ(v.width, 64);
  EXPECT_EQ(v.height, 36);
  EXPECT_EQ(v.frames, 12);
  ASSERT_TRUE(v.first.defined());
  double p = psnr(v.first, frames[0]);
  EXPECT_GT(p, 30.0);
  std::cout << "first-frame PSNR " << p << " dB\n";
  int n = 0;
  for (auto& e : std::filesystem::directory_iterator(dir)) n += e.is_regular_file();
  EXPECT_EQ(n, 1);  // no temp files left
  remove_tree(dir);
}

TEST(Mp4, OddSizesArePaddedToEven) {
  if (!mp4_available()) GTEST_SKIP() << "no MP4 output here (no encoder in this FFmpeg, or built without FFmpeg)";
  auto dir = temp_dir("mp4_odd");
  std::string path = (dir / "odd.mp4").string();
  auto frames = gradient_frames(5, 35, 63, false);
  write_mp4(path, frames, 24.0);
  auto v = decode_mp4(path);
  EXPECT_EQ(v.width, 64);
  EXPECT_EQ(v.height, 36);
  EXPECT_EQ(v.frames, 5);
  EXPECT_GT(psnr(v.first.narrow(0, 0, 35).narrow(1, 0, 63), frames[0]), 30.0);
  remove_tree(dir);
}

TEST(Mp4, UnavailableIsAClearError) {
  if (mp4_available()) GTEST_SKIP() << "this build writes MP4 (encoder " << mp4_encoder_name() << ")";
  EXPECT_EQ(mp4_encoder_name(), "");
  auto dir = temp_dir("mp4_off");
  std::string path = (dir / "off.mp4").string();
  try {
    write_mp4(path, gradient_frames(2), 10);
    FAIL() << "write_mp4 wrote without an encoder";
  } catch (const std::runtime_error& e) {
    std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_TRUE(msg.find("without FFmpeg") != std::string::npos || msg.find("encoder") != std::string::npos) << msg;
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  remove_tree(dir);
}

TEST(Mp4, RejectsMismatchedFrames) {
  auto dir = temp_dir("mp4_bad");
  std::string path = (dir / "bad.mp4").string();
  auto frames = gradient_frames(2);
  frames.push_back(torch::zeros({8, 8, 3}, torch::kUInt8));
  try {
    write_mp4(path, frames, 10);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("frame 2"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  remove_tree(dir);
}

}  // namespace
}  // namespace uplvsm::io
