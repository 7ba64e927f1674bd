// The built-in object dataset (`uplvsm make-dataset --kind objects`): the paper's Objaverse setting in miniature.
// One procedural object per scene (2-5 textured spheres and boxes around the origin, Lambertian shading from one
// directional light plus ambient) on a plain gray backdrop, seen from independent random cameras on a sphere
// around it that look at its centre: the views have no order (dataset.json says "unordered").
#pragma once
#include <cstdint>

#include "uplvsm/data/synthetic/builtin_dataset.h"

namespace uplvsm::data {

struct ObjectSceneOptions {
  int height = 96;
  int width = 96;
  int views = 24;              // the paper's Objaverse renders: 24 random views per object
  double texture_scale = 1.0;  // scales every surface pattern's size
  int jpeg_quality = 90;
  double fov_degrees = 45;  // field of view across the shorter image side
  // Camera elevation above the object's equator, uniform in [min, max] degrees; azimuth uniform in [0, 360).
  double min_elevation_degrees = -10, max_elevation_degrees = 50;
};

// Renders one object scene: key builtin_scene_key(seed), url "builtin://object/<seed>".
SceneRender render_object(uint64_t seed, const ObjectSceneOptions& opt);

// The objects as a generator for write_generated_dataset: unordered views; evaluation views of a test scene are
// two random context views and three random other views as targets (sorted), with their overlap.
SceneGenerator object_generator(const ObjectSceneOptions& opt);

}  // namespace uplvsm::data
