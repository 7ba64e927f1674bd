// Procedural objects seen from random cameras on a sphere; see object_scenes.h.
#include "uplvsm/data/synthetic/object_scenes.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include <fmt/format.h>

namespace uplvsm::data {
namespace {

using namespace synthetic;

struct Object {
  std::vector<Sphere> spheres;
  std::vector<Box> boxes;
  Vec3 light_dir;  // direction the light travels
  double ambient = 0.5;
  Vec3 background = {0.5, 0.5, 0.5};  // the paper's object training converged on a gray backdrop, not white
  std::vector<Camera> cameras;
  double fx = 100;
};

Vec3 random_direction(Rng& rng) {
  for (;;) {
    Vec3 v = {rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
    const double n2 = dot(v, v);
    if (n2 > 1e-4 && n2 <= 1) return v * (1.0 / std::sqrt(n2));
  }
}

// One part: a sphere or a yawed box of about `size` (half extent) at `centre`; returns its bounding radius.
double add_part(Rng& rng, Object& o, Vec3 centre, double size, double hue, double texture_scale) {
  Texture tex = random_texture(rng, hue, 0.5 * size * texture_scale, 1.4 * size * texture_scale);
  if (rng.uniform() < 0.5) {
    o.spheres.push_back({centre, size, tex});
    return size;
  }
  Vec3 half = {size * rng.uniform(0.6, 1.2), size * rng.uniform(0.6, 1.2), size * rng.uniform(0.6, 1.2)};
  double yaw = rng.uniform(0, M_PI);
  o.boxes.push_back({centre, half, yaw, tex, std::cos(yaw), std::sin(yaw)});
  return std::sqrt(dot(half, half));
}

// A body at the origin with 1-4 smaller parts stuck to it, scaled so the whole fits in the unit sphere.
void sample_shape(Rng& rng, Object& o, double texture_scale) {
  const double hue = rng.uniform();
  const double body = rng.uniform(0.45, 0.7);
  double reach = add_part(rng, o, {0, 0, 0}, body, hue, texture_scale);
  const int parts = static_cast<int>(rng.integer(1, 4));
  for (int k = 0; k < parts; ++k) {
    const double size = body * rng.uniform(0.35, 0.7);
    const Vec3 centre = random_direction(rng) * (body * rng.uniform(0.8, 1.15));
    const double r = add_part(rng, o, centre, size, hue + rng.uniform(0.15, 0.85), texture_scale);
    reach = std::max(reach, std::sqrt(dot(centre, centre)) + r);
  }
  const double s = 1.0 / reach;
  for (auto& sp : o.spheres) sp.center = sp.center * s, sp.radius *= s;
  for (auto& b : o.boxes) b.center = b.center * s, b.half = b.half * s;
}

// Looks at a point near the origin from `distance` at the given azimuth/elevation (y is down: up is -y).
Camera look_at_origin(Rng& rng, double azimuth, double elevation, double distance) {
  Vec3 position = {distance * std::cos(elevation) * std::sin(azimuth), -distance * std::sin(elevation),
                   distance * std::cos(elevation) * std::cos(azimuth)};
  Vec3 target = {rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1)};
  Vec3 f = normalize(target - position);
  Vec3 r = normalize(cross({0, 1, 0}, f));  // OpenCV: x = y cross z with y (down) and z (forward)
  return {position, {r, cross(f, r), f}};
}

Object sample_object(uint64_t seed, const ObjectSceneOptions& opt) {
  Rng rng(seed);
  Object o;
  sample_shape(rng, o, opt.texture_scale);
  o.light_dir = normalize({rng.uniform(-1, 1), rng.uniform(0.3, 1.0), rng.uniform(-1, 1)});
  o.ambient = rng.uniform(0.35, 0.55);
  o.fx = std::min(opt.width, opt.height) / 2.0 / std::tan(opt.fov_degrees * M_PI / 360.0);
  const double lo = opt.min_elevation_degrees * M_PI / 180, hi = opt.max_elevation_degrees * M_PI / 180;
  for (int i = 0; i < opt.views; ++i) {
    const double azimuth = rng.uniform(0, 2 * M_PI), elevation = rng.uniform(lo, hi);
    o.cameras.push_back(look_at_origin(rng, azimuth, elevation, rng.uniform(2.2, 2.6)));
  }
  return o;
}

Vec3 trace(const Object& o, const Camera& cam, double cx, double cy, int u, int v, float* depth) {
  Vec3 dc = {(u + 0.5 - cx) / o.fx, (v + 0.5 - cy) / o.fx, 1.0};
  // World direction with camera-z component 1, so the hit parameter t is the camera z-depth.
  Vec3 d = cam.axes[0] * dc.x + cam.axes[1] * dc.y + cam.axes[2] * dc.z;
  Hit hit;
  for (size_t k = 0; k < o.spheres.size(); ++k) hit_sphere(o.spheres[k], static_cast<int>(k), cam.position, d, hit);
  for (size_t k = 0; k < o.boxes.size(); ++k) hit_box(o.boxes[k], static_cast<int>(k), cam.position, d, hit);
  if (hit.kind < 0) {
    *depth = std::numeric_limits<float>::infinity();
    return o.background;
  }
  double dist = hit.t * std::sqrt(dot(d, d));
  double cos_incidence = std::max(std::abs(dot(hit.normal, d)) / std::sqrt(dot(d, d)), 0.1);
  double footprint = dist / o.fx / cos_incidence;
  Vec3 albedo = hit.kind == 1 ? sphere_albedo(o.spheres[hit.index], hit, footprint)
                              : box_albedo(o.boxes[hit.index], hit, footprint);
  *depth = static_cast<float>(hit.t);
  double lambert = std::max(0.0, -dot(hit.normal, o.light_dir));
  return albedo * (o.ambient + (1 - o.ambient) * lambert);
}

// Two random context views and three random other views as targets (sorted).
std::optional<EvalEntry> object_eval_entry(const SceneRender& r, uint64_t seed) {
  const int64_t n = static_cast<int64_t>(r.scene.images.size());
  if (n < 5) return std::nullopt;
  Rng rng(seed ^ 0x0B1EC7E7A1ull);
  std::vector<int64_t> order(n);
  for (int64_t i = 0; i < n; ++i) order[i] = i;
  for (int64_t j = 0; j < 5; ++j) std::swap(order[j], order[rng.integer(j, n - 1)]);
  EvalEntry e;
  e.key = r.scene.key;
  e.context = {order[0], order[1]};
  e.target = {order[2], order[3], order[4]};
  std::sort(e.target.begin(), e.target.end());
  e.overlap = std::round(context_overlap(r, order[0], order[1]) * 1e5) / 1e5;
  return e;
}

void check_options(const ObjectSceneOptions& opt) {
  if (opt.height < 2 || opt.width < 2 || opt.views < 1 || !(opt.texture_scale > 0) || opt.jpeg_quality < 1 ||
      opt.jpeg_quality > 100 || !(opt.fov_degrees > 0 && opt.fov_degrees < 180) ||
      !(opt.min_elevation_degrees <= opt.max_elevation_degrees) || std::abs(opt.min_elevation_degrees) >= 90 ||
      std::abs(opt.max_elevation_degrees) >= 90)
    throw std::runtime_error(
        fmt::format("object scenes: bad options (height {}, width {}, views {}, texture_scale {}, "
                    "jpeg_quality {}, fov {}, elevation [{}, {}])",
                    opt.height, opt.width, opt.views, opt.texture_scale, opt.jpeg_quality, opt.fov_degrees,
                    opt.min_elevation_degrees, opt.max_elevation_degrees));
}

}  // namespace

SceneRender render_object(uint64_t seed, const ObjectSceneOptions& opt) {
  check_options(opt);
  const Object o = sample_object(seed, opt);
  const double cx = opt.width / 2.0, cy = opt.height / 2.0;
  auto tracer = [&](const Camera& cam, int u, int v, float* depth) { return trace(o, cam, cx, cy, u, v, depth); };
  return render_scene(o.cameras, o.fx, opt.height, opt.width, opt.jpeg_quality, tracer, builtin_scene_key(seed),
                      fmt::format("builtin://object/{}", seed));
}

SceneGenerator object_generator(const ObjectSceneOptions& opt) {
  check_options(opt);
  SceneGenerator g;
  g.name = "objects";
  g.ordered_views = false;
  g.seed_salt = 0x0B1EC75ull;
  g.render = [opt](uint64_t seed) { return render_object(seed, opt); };
  g.eval_entry = [](const SceneRender& r, uint64_t seed) { return object_eval_entry(r, seed); };
  return g;
}

}  // namespace uplvsm::data
