// Users' own photo files as views of one scene: read (JPEG/PNG) and made views by data::preprocess_photo (resized and
// centre-cropped like the training data, a pinhole camera of the given horizontal field of view, identity pose).
// What `uplvsm render --images`, `study --images`, the Python module and the C++ example feed the model.
#pragma once
#include <string>
#include <vector>

#include "uplvsm/data/preprocess.h"
#include "uplvsm/data/scene.h"

namespace uplvsm::data {

// One view per path, in order: images [V, 3, H, W], fxfycxcy [V, 4] pixels, c2w [V, 4, 4] identity, frames 0..V-1.
// Errors name the file (unreadable, not JPEG/PNG) or the photo whose preprocessed size differs from the first's; a
// field of view outside (0, 180) degrees is an std::invalid_argument.
SceneViews load_photos(const std::vector<std::string>& paths, double fov_degrees, const PreprocessOptions& opt);

}  // namespace uplvsm::data
