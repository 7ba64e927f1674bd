// MP4 writer through libavformat / libavcodec / libswscale (see mp4_writer.h). Without UPLVSM_WITH_FFMPEG (FFmpeg
// is an optional build dependency) only the stubs at the end are compiled: write_mp4 throws a clear error.
#include "uplvsm/io/mp4_writer.h"

#include <stdexcept>

#include "uplvsm/io/video_frames.h"

#ifdef UPLVSM_WITH_FFMPEG
#include <filesystem>

#include "uplvsm/io/atomic_file.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

namespace uplvsm::io {
namespace {

std::string av_error(int code) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {0};
  av_strerror(code, buf, sizeof buf);
  return buf;
}

void check_av(int ret, const std::string& path, const char* what) {
  if (ret < 0) throw std::runtime_error("mp4 '" + path + "': " + what + " failed: " + av_error(ret));
}

const AVCodec* pick_encoder() {
  if (const AVCodec* c = avcodec_find_encoder_by_name("libx264")) return c;
  return avcodec_find_encoder(AV_CODEC_ID_MPEG4);
}

// Everything FFmpeg allocates for one file, freed in the destructor (also on errors).
struct Mp4Encoder {
  AVFormatContext* oc = nullptr;
  AVCodecContext* cc = nullptr;
  AVStream* st = nullptr;
  SwsContext* sws = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* pkt = nullptr;
  ~Mp4Encoder() {
    sws_freeContext(sws);
    av_frame_free(&frame);
    av_packet_free(&pkt);
    avcodec_free_context(&cc);
    if (oc && oc->pb) avio_closep(&oc->pb);
    avformat_free_context(oc);
  }
};

void configure_codec(Mp4Encoder& e, const AVCodec* codec, int w, int h, double fps) {
  AVRational rate = av_d2q(fps, 65535);
  e.cc->width = w;
  e.cc->height = h;
  e.cc->framerate = rate;
  e.cc->time_base = av_inv_q(rate);
  e.cc->pix_fmt = AV_PIX_FMT_YUV420P;
  // swscale's default RGB->YUV is BT.601 limited range; tag it so players convert back the same way.
  e.cc->color_range = AVCOL_RANGE_MPEG;
  e.cc->colorspace = AVCOL_SPC_SMPTE170M;
  e.cc->color_primaries = AVCOL_PRI_BT709;
  e.cc->color_trc = AVCOL_TRC_IEC61966_2_1;
  if (std::string(codec->name) == "libx264") {
    av_opt_set(e.cc->priv_data, "crf", "18", 0);
    av_opt_set(e.cc->priv_data, "preset", "medium", 0);
  } else {
    e.cc->flags |= AV_CODEC_FLAG_QSCALE;
    e.cc->global_quality = FF_QP2LAMBDA * 2;  // qscale 2: near the best MPEG-4 part 2 can do
    e.cc->gop_size = 12;
  }
  if (e.oc->oformat->flags & AVFMT_GLOBALHEADER) e.cc->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
}

void drain_packets(Mp4Encoder& e, const std::string& path) {
  while (true) {
    int ret = avcodec_receive_packet(e.cc, e.pkt);
    if (ret == AVERROR(EAGAIN) || ret == AVERROR_EOF) return;
    check_av(ret, path, "avcodec_receive_packet");
    av_packet_rescale_ts(e.pkt, e.cc->time_base, e.st->time_base);
    e.pkt->stream_index = e.st->index;
    check_av(av_interleaved_write_frame(e.oc, e.pkt), path, "av_interleaved_write_frame");
  }
}

// Pads odd sizes to even by replicating the last column / row (yuv420p needs even dimensions).
torch::Tensor pad_to_even(const torch::Tensor& f) {
  torch::Tensor out = f;
  if (out.size(1) % 2) out = torch::cat({out, out.narrow(1, out.size(1) - 1, 1)}, 1);
  if (out.size(0) % 2) out = torch::cat({out, out.narrow(0, out.size(0) - 1, 1)}, 0);
  return out.contiguous();
}

void encode_frames(Mp4Encoder& e, const std::vector<torch::Tensor>& frames, const std::string& path) {
  int w = e.cc->width, h = e.cc->height;
  for (size_t i = 0; i < frames.size(); ++i) {
    torch::Tensor rgb = pad_to_even(frames[i]);
    check_av(av_frame_make_writable(e.frame), path, "av_frame_make_writable");
    const uint8_t* src[1] = {rgb.data_ptr<uint8_t>()};
    int src_stride[1] = {3 * w};
    sws_scale(e.sws, src, src_stride, 0, h, e.frame->data, e.frame->linesize);
    e.frame->pts = int64_t(i);
    check_av(avcodec_send_frame(e.cc, e.frame), path, "avcodec_send_frame");
    drain_packets(e, path);
  }
  check_av(avcodec_send_frame(e.cc, nullptr), path, "avcodec_send_frame (flush)");
  drain_packets(e, path);
}

void encode_mp4_file(const std::string& tmp, const std::string& path, const std::vector<torch::Tensor>& frames,
                     double fps) {
  const AVCodec* codec = pick_encoder();
  if (!codec) throw std::runtime_error("mp4 '" + path + "': neither libx264 nor mpeg4 encoder is available");
  int w = int(frames[0].size(1) + frames[0].size(1) % 2), h = int(frames[0].size(0) + frames[0].size(0) % 2);
  Mp4Encoder e;
  check_av(avformat_alloc_output_context2(&e.oc, nullptr, "mp4", tmp.c_str()), path, "avformat_alloc_output_context2");
  e.st = avformat_new_stream(e.oc, nullptr);
  e.cc = avcodec_alloc_context3(codec);
  e.frame = av_frame_alloc();
  e.pkt = av_packet_alloc();
  if (!e.st || !e.cc || !e.frame || !e.pkt) throw std::runtime_error("mp4 '" + path + "': out of memory");
  configure_codec(e, codec, w, h, fps);
  check_av(avcodec_open2(e.cc, codec, nullptr), path, std::string("opening encoder ").append(codec->name).c_str());
  check_av(avcodec_parameters_from_context(e.st->codecpar, e.cc), path, "avcodec_parameters_from_context");
  e.st->time_base = e.cc->time_base;
  e.st->avg_frame_rate = e.cc->framerate;
  e.frame->format = AV_PIX_FMT_YUV420P;
  e.frame->width = w;
  e.frame->height = h;
  check_av(av_frame_get_buffer(e.frame, 0), path, "av_frame_get_buffer");
  e.sws = sws_getContext(w, h, AV_PIX_FMT_RGB24, w, h, AV_PIX_FMT_YUV420P, SWS_BILINEAR | SWS_ACCURATE_RND, nullptr,
                         nullptr, nullptr);
  if (!e.sws) throw std::runtime_error("mp4 '" + path + "': cannot create the RGB->YUV converter");
  check_av(avio_open(&e.oc->pb, tmp.c_str(), AVIO_FLAG_WRITE), path, "avio_open");
  AVDictionary* opts = nullptr;
  av_dict_set(&opts, "movflags", "faststart", 0);  // index up front: playable while downloading
  int ret = avformat_write_header(e.oc, &opts);
  av_dict_free(&opts);
  check_av(ret, path, "avformat_write_header");
  encode_frames(e, frames, path);
  check_av(av_write_trailer(e.oc), path, "av_write_trailer");
  check_av(avio_closep(&e.oc->pb), path, "closing the output");
}

}  // namespace

void write_mp4(const std::string& path, const std::vector<torch::Tensor>& frames_hwc_u8, double fps) {
  auto frames = checked_video_frames(path, frames_hwc_u8, fps);
  // FFmpeg/x264 log banners and statistics at info level; only errors are worth showing.
  if (av_log_get_level() > AV_LOG_ERROR) av_log_set_level(AV_LOG_ERROR);
  std::string tmp = temp_path_for(path);
  try {
    encode_mp4_file(tmp, path, frames, fps);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw;
  }
  commit_temp_file(tmp, path);
}

bool mp4_available() { return !mp4_encoder_name().empty(); }

std::string mp4_encoder_name() {
  if (!av_guess_format("mp4", nullptr, nullptr)) return "";
  const AVCodec* c = pick_encoder();
  return c ? c->name : "";
}

}  // namespace uplvsm::io

#else  // !UPLVSM_WITH_FFMPEG

namespace uplvsm::io {

// Bad frames get the same error as with FFmpeg; only valid requests learn that MP4 is off.
void write_mp4(const std::string& path, const std::vector<torch::Tensor>& frames_hwc_u8, double fps) {
  checked_video_frames(path, frames_hwc_u8, fps);
  throw std::runtime_error("mp4 '" + path +
                           "': this uplvsm was built without FFmpeg, so it cannot write MP4 (configure with the "
                           "libavformat/libavcodec/libswscale dev packages installed and -DUPLVSM_WITH_FFMPEG=ON, or "
                           "write a GIF / PNG frames instead)");
}

bool mp4_available() { return false; }

std::string mp4_encoder_name() { return ""; }

}  // namespace uplvsm::io

#endif  // UPLVSM_WITH_FFMPEG
