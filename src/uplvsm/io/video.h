// Writing frame sequences as animations: one include for both writers, the GIF encoder (gif_writer.h) and MP4
// through FFmpeg (mp4_writer.h, optional at build time), so existing `#include "uplvsm/io/video.h"` keeps working.
#pragma once
#include "uplvsm/io/gif_writer.h"
#include "uplvsm/io/mp4_writer.h"
