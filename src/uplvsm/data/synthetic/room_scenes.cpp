// Procedural indoor walkthroughs: scene sampling (room, textures, objects, camera path), a small ray caster, and
// the dataset writer. World axes follow the cameras (OpenCV): y points down, so the floor is at +floor_y.
#include "uplvsm/data/synthetic/room_scenes.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <stdexcept>
#include <thread>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/data/view_sampler.h"
#include "uplvsm/io/image.h"

namespace uplvsm::data {
namespace {

// ---------------------------------------------------------------------------------------------------- vectors
struct Vec3 {
  double x = 0, y = 0, z = 0;
};
Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3 operator*(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Vec3 cross(Vec3 a, Vec3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
Vec3 normalize(Vec3 a) { return a * (1.0 / std::sqrt(dot(a, a))); }
Vec3 lerp(Vec3 a, Vec3 b, double t) { return a + (b - a) * t; }
double lerp1(double a, double b, double t) { return a + (b - a) * t; }
double smoothstep(double e0, double e1, double x) {
  double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

// ---------------------------------------------------------------------------------------------------- random
uint64_t splitmix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Explicit formulas (not std:: distributions, whose output is implementation-defined) keep scenes identical
// across standard libraries.
struct Rng {
  std::mt19937_64 engine;
  explicit Rng(uint64_t seed) : engine(splitmix64(seed)) {}
  double uniform() { return static_cast<double>(engine() >> 11) * (1.0 / 9007199254740992.0); }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  int64_t integer(int64_t lo, int64_t hi) { return uniform_int(engine, lo, hi); }
};

// A colour from hue/saturation/value in [0,1].
Vec3 hsv(double h, double s, double v) {
  h = (h - std::floor(h)) * 6.0;
  int i = static_cast<int>(h) % 6;
  double f = h - std::floor(h), p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
  const Vec3 table[6] = {{v, t, p}, {q, v, p}, {p, v, t}, {p, q, v}, {t, p, v}, {v, p, q}};
  return table[i];
}

// ---------------------------------------------------------------------------------------------------- textures
// Large smooth patterns only (a tiny network should be able to learn them): a colour gradient over metres, mixed
// with a soft-edged checker, stripes or dots in a third colour.
struct Texture {
  int kind = 0;  // 0 checker, 1 stripes, 2 dots
  Vec3 a, b, c;
  double period = 1.0, angle = 0.0, grad_length = 2.0, grad_angle = 0.0, strength = 0.4;
  // Cached trigonometry of the angles (the texture is evaluated once per pixel).
  double cos_angle = 1, sin_angle = 0, cos_grad = 1, sin_grad = 0;
  void cache() {
    cos_angle = std::cos(angle), sin_angle = std::sin(angle);
    cos_grad = std::cos(grad_angle), sin_grad = std::sin(grad_angle);
  }
};

Texture random_texture(Rng& rng, double base_hue, double period_lo, double period_hi) {
  Texture t;
  t.kind = static_cast<int>(rng.integer(0, 2));
  double h = base_hue + rng.uniform(-0.12, 0.12);
  t.a = hsv(h, rng.uniform(0.2, 0.6), rng.uniform(0.55, 0.9));
  t.b = hsv(h + rng.uniform(-0.15, 0.15), rng.uniform(0.2, 0.7), rng.uniform(0.4, 0.85));
  t.c = hsv(rng.uniform(), rng.uniform(0.3, 0.8), rng.uniform(0.25, 0.9));
  t.period = rng.uniform(period_lo, period_hi);
  t.angle = rng.uniform(0, M_PI);
  t.grad_length = rng.uniform(1.5, 4.0);
  t.grad_angle = rng.uniform(0, 2 * M_PI);
  t.strength = rng.uniform(0.3, 0.6);
  t.cache();
  return t;
}

// Fades a pattern towards its mean once a pixel covers a good part of its feature size `scale`: a cheap
// pre-filter, so distant or grazing surfaces show no aliasing noise (there is one ray per pixel).
double fade_detail(double value, double mean, double scale, double footprint) {
  return lerp1(value, mean, smoothstep(0.2 * scale, 0.6 * scale, footprint));
}

// `footprint`: approximate size (metres) of the pixel's footprint on the surface.
Vec3 eval_texture(const Texture& t, double u, double v, double footprint) {
  double g = 0.5 + 0.5 * std::sin((u * t.cos_grad + v * t.sin_grad) / t.grad_length);
  Vec3 base = lerp(t.a, t.b, g);
  const double w = 2 * M_PI / t.period;
  double p = 0, mean = 0.5;
  if (t.kind == 0) {
    p = smoothstep(-0.25, 0.25, std::sin(w * u) * std::sin(w * v));
  } else if (t.kind == 1) {
    p = smoothstep(-0.3, 0.3, std::sin(w * (u * t.cos_angle + v * t.sin_angle)));
  } else {
    p = smoothstep(0.35, 0.65, std::cos(w * u) * std::cos(w * v));
    mean = 0.2;  // area share of the dots
  }
  return lerp(base, t.c, t.strength * fade_detail(p, mean, 0.5 * t.period, footprint));
}

struct FloorTexture {
  Vec3 wood_a, wood_b;
  double plank_width = 0.3, plank_length = 1.5;
  bool along_z = false;  // boards run along z instead of x
  uint64_t salt = 0;
};

// Planks: each board a shade between two wood colours, soft dark grooves, a gentle grain along the board.
Vec3 eval_floor(const FloorTexture& f, double x, double z, double footprint) {
  double u = f.along_z ? z : x, v = f.along_z ? x : z;
  double row = std::floor(v / f.plank_width);
  double shifted = u / f.plank_length + 0.37 * row;
  double col = std::floor(shifted);
  uint64_t cell = static_cast<uint64_t>(static_cast<int64_t>(row) * 7919 + static_cast<int64_t>(col) * 104729);
  uint64_t h = splitmix64(f.salt ^ splitmix64(cell));
  double shade = fade_detail(static_cast<double>(h >> 11) / 9007199254740992.0, 0.5, f.plank_width, footprint);
  Vec3 wood = lerp(f.wood_a, f.wood_b, shade);
  double dv = std::min(v / f.plank_width - row, 1 - (v / f.plank_width - row)) * f.plank_width;
  double du = std::min(shifted - col, 1 - (shifted - col)) * f.plank_length;
  double groove = fade_detail(smoothstep(0.0, 0.04, std::min(dv, du)), 0.85, 0.5 * f.plank_width, footprint);
  double grain = 1.0 + 0.05 * std::sin(u * 2.5 + row * 1.7);
  return wood * ((0.6 + 0.4 * groove) * grain);
}

// ---------------------------------------------------------------------------------------------------- scene
struct Sphere {
  Vec3 center;
  double radius = 0.4;
  Texture tex;
};

struct Box {
  Vec3 center, half;  // half extents in the box frame
  double yaw = 0;     // rotation about the world y axis
  Texture tex;
  double cos_yaw = 1, sin_yaw = 0;
};

struct Camera {
  Vec3 position;
  std::array<Vec3, 3> axes;  // right, down, forward (the columns of the c2w rotation)
};

struct Room {
  double x_half = 4, z_half = 5, floor_y = 1.5, ceiling_y = -1.3;
  std::array<Texture, 4> walls;  // x-, x+, z-, z+
  Texture ceiling;
  FloorTexture floor;
  std::vector<Sphere> spheres;
  std::vector<Box> boxes;
  Vec3 light_dir;  // direction the light travels
  double ambient = 0.5;
  std::vector<Camera> cameras;
  double fx = 100;
};

// Nearest intersection so far; the texture is evaluated once, for the final hit only.
struct Hit {
  double t = 1e30;
  int kind = -1;   // 0 room surface, 1 sphere, 2 box
  int index = -1;  // surface (walls x-, x+, z-, z+, floor, ceiling) or object index
  Vec3 normal;
  Vec3 local;      // box: hit point in the box frame
  int axis = 0;    // box: axis of the face hit
};

// Distance from o along direction f to the room's boundary (o inside the room).
double view_depth(const Room& room, Vec3 o, Vec3 f) {
  double t = 1e30;
  if (f.x != 0) t = std::min(t, ((f.x > 0 ? room.x_half : -room.x_half) - o.x) / f.x);
  if (f.z != 0) t = std::min(t, ((f.z > 0 ? room.z_half : -room.z_half) - o.z) / f.z);
  if (f.y != 0) t = std::min(t, ((f.y > 0 ? room.floor_y : room.ceiling_y) - o.y) / f.y);
  return t;
}

// Walkthrough path: forward motion, heading drifting slowly and wobbling, view yaw/pitch near the heading.
std::vector<Camera> sample_path(Rng& rng, const Room& room, int frames, double spacing) {
  const double margin = 0.9, min_view_depth = 3.0;
  for (int attempt = 0;; ++attempt) {
    double speed = rng.uniform(0.05, 0.09) * spacing * std::pow(0.8, attempt / 8);
    double heading = rng.uniform(0, 2 * M_PI), drift = rng.uniform(-0.02, 0.02) * spacing;
    double wobble = rng.uniform(0.05, 0.2), wobble_freq = rng.uniform(0.05, 0.15) * spacing;
    double phase = rng.uniform(0, 2 * M_PI), look = rng.uniform(-0.12, 0.12);
    double pitch0 = rng.uniform(-0.05, 0.12), pitch_amp = rng.uniform(0.0, 0.05);
    double height = room.floor_y - rng.uniform(1.3, 1.7);
    std::vector<Vec3> pos(frames);
    std::vector<double> yaw(frames), pitch(frames);
    Vec3 p;
    for (int i = 0; i < frames; ++i) {
      double h = heading + drift * i + wobble * std::sin(wobble_freq * i + phase);
      pos[i] = {p.x, height + 0.02 * std::sin(0.3 * spacing * i + phase), p.z};
      yaw[i] = h + look * std::cos(0.5 * wobble_freq * i + phase);
      pitch[i] = pitch0 + pitch_amp * std::sin(0.7 * wobble_freq * i + 2 * phase);
      p = p + Vec3{std::sin(h), 0, std::cos(h)} * speed;
    }
    double x0 = 1e9, x1 = -1e9, z0 = 1e9, z1 = -1e9;
    for (const auto& q : pos) x0 = std::min(x0, q.x), x1 = std::max(x1, q.x), z0 = std::min(z0, q.z), z1 = std::max(z1, q.z);
    double free_x = 2 * (room.x_half - margin) - (x1 - x0), free_z = 2 * (room.z_half - margin) - (z1 - z0);
    if ((free_x < 0 || free_z < 0) && attempt < 200) continue;
    // Put the path's bounding box at a random spot where it stays `margin` away from the walls (a path too long
    // for the room is retried, slower every 8 attempts).
    Vec3 shift = {-room.x_half + margin - x0 + rng.uniform(0, std::max(0.0, free_x)), 0,
                  -room.z_half + margin - z0 + rng.uniform(0, std::max(0.0, free_z))};
    std::vector<Camera> cams(frames);
    bool open_view = true;
    for (int i = 0; i < frames; ++i) {
      Vec3 f = {std::sin(yaw[i]) * std::cos(pitch[i]), std::sin(pitch[i]), std::cos(yaw[i]) * std::cos(pitch[i])};
      Vec3 r = normalize(cross({0, 1, 0}, f));  // OpenCV: x = y cross z with y (down) and z (forward)
      Vec3 d = cross(f, r);
      cams[i] = {pos[i] + shift, {r, d, f}};
      open_view = open_view && view_depth(room, cams[i].position, f) > min_view_depth;
    }
    // A camera staring at a wall from close by sees one flat colour: retry (like a walkthrough facing the room).
    if (!open_view && attempt < 200) continue;
    return cams;
  }
}

double distance_to_path_xz(const std::vector<Camera>& cams, double x, double z) {
  double best = 1e30;
  for (const auto& c : cams) best = std::min(best, std::hypot(c.position.x - x, c.position.z - z));
  return best;
}

// Objects stand on the floor, away from the camera path and from each other; most are put ahead of the camera.
void place_objects(Rng& rng, Room& room, double base_hue, double texture_scale) {
  int count = static_cast<int>(rng.integer(3, 6));
  const Camera& last = room.cameras.back();
  std::vector<std::pair<Vec3, double>> placed;  // footprint centre, radius
  for (int k = 0; k < count; ++k) {
    bool sphere = rng.uniform() < 0.5;
    double size = rng.uniform(0.25, 0.6);
    for (int attempt = 0; attempt < 200; ++attempt) {
      double x, z;
      if (attempt < 100 && rng.uniform() < 0.7) {
        Vec3 f = last.axes[2], r = last.axes[0];
        double ahead = rng.uniform(1.0, 4.0), side = rng.uniform(-2.0, 2.0);
        x = last.position.x + f.x * ahead + r.x * side;
        z = last.position.z + f.z * ahead + r.z * side;
      } else {
        x = rng.uniform(-room.x_half, room.x_half);
        z = rng.uniform(-room.z_half, room.z_half);
      }
      double reach = size * 1.5;
      if (std::abs(x) > room.x_half - reach || std::abs(z) > room.z_half - reach) continue;
      if (distance_to_path_xz(room.cameras, x, z) < reach + 0.6) continue;
      bool clash = false;
      for (const auto& [c, r] : placed) clash = clash || std::hypot(c.x - x, c.z - z) < r + reach + 0.1;
      if (clash) continue;
      Texture tex = random_texture(rng, base_hue + rng.uniform(0.2, 0.8), size * 0.6 * texture_scale,
                                   size * 1.4 * texture_scale);
      if (sphere) {
        room.spheres.push_back({{x, room.floor_y - size, z}, size, tex});
      } else {
        Vec3 half = {size * rng.uniform(0.6, 1.2), rng.uniform(0.2, 0.7), size * rng.uniform(0.6, 1.2)};
        double yaw = rng.uniform(0, M_PI);
        room.boxes.push_back({{x, room.floor_y - half.y, z}, half, yaw, tex, std::cos(yaw), std::sin(yaw)});
      }
      placed.push_back({{x, 0, z}, reach});
      break;
    }
  }
}

Room sample_room(uint64_t seed, const RoomSceneOptions& opt) {
  Rng rng(seed);
  Room room;
  room.x_half = rng.uniform(3.0, 5.0);
  room.z_half = rng.uniform(4.0, 7.0);
  double height = rng.uniform(2.6, 3.4);
  room.floor_y = 1.5;
  room.ceiling_y = room.floor_y - height;
  double hue = rng.uniform();
  const double ts = opt.texture_scale;
  for (auto& wall : room.walls) wall = random_texture(rng, hue + rng.uniform(-0.3, 0.3), 0.8 * ts, 2.0 * ts);
  room.ceiling = random_texture(rng, hue, 1.5 * ts, 3.0 * ts);
  room.ceiling.a = lerp(room.ceiling.a, {0.95, 0.95, 0.92}, 0.6);
  room.ceiling.b = lerp(room.ceiling.b, {0.9, 0.9, 0.9}, 0.6);
  room.ceiling.strength *= 0.5;
  double wood_hue = rng.uniform(0.04, 0.12);
  room.floor.wood_a = hsv(wood_hue, rng.uniform(0.4, 0.7), rng.uniform(0.45, 0.75));
  room.floor.wood_b = hsv(wood_hue + rng.uniform(-0.03, 0.03), rng.uniform(0.3, 0.7), rng.uniform(0.3, 0.6));
  room.floor.plank_width = rng.uniform(0.3, 0.55) * ts;
  room.floor.plank_length = rng.uniform(1.0, 2.2) * ts;
  room.floor.along_z = rng.integer(0, 1) == 1;
  room.floor.salt = splitmix64(seed ^ 0xF100F100ull);
  room.light_dir = normalize({rng.uniform(-0.6, 0.6), 1.0, rng.uniform(-0.6, 0.6)});
  room.ambient = rng.uniform(0.4, 0.6);
  double fov = rng.uniform(55.0, 75.0) * M_PI / 180.0;  // horizontal
  room.fx = opt.width / 2.0 / std::tan(fov / 2);
  room.cameras = sample_path(rng, room, opt.frames, opt.frame_spacing);
  place_objects(rng, room, hue, opt.texture_scale);
  return room;
}

// ---------------------------------------------------------------------------------------------------- ray casting
// The camera is inside the box: the wall hit is the nearest exit plane.
void hit_room(const Room& room, Vec3 o, Vec3 d, Hit& hit) {
  auto try_plane = [&](double t, Vec3 n, int surface) {
    if (t <= 1e-9 || t >= hit.t) return;
    hit.t = t;
    hit.normal = n;
    hit.kind = 0;
    hit.index = surface;
  };
  if (d.x < 0) try_plane((-room.x_half - o.x) / d.x, {1, 0, 0}, 0);
  if (d.x > 0) try_plane((room.x_half - o.x) / d.x, {-1, 0, 0}, 1);
  if (d.z < 0) try_plane((-room.z_half - o.z) / d.z, {0, 0, 1}, 2);
  if (d.z > 0) try_plane((room.z_half - o.z) / d.z, {0, 0, -1}, 3);
  if (d.y > 0) try_plane((room.floor_y - o.y) / d.y, {0, -1, 0}, 4);
  if (d.y < 0) try_plane((room.ceiling_y - o.y) / d.y, {0, 1, 0}, 5);
}

void hit_sphere(const Sphere& s, int index, Vec3 o, Vec3 d, Hit& hit) {
  Vec3 oc = o - s.center;
  double a = dot(d, d), b = dot(oc, d), c = dot(oc, oc) - s.radius * s.radius;
  double disc = b * b - a * c;
  if (disc < 0) return;
  double t = (-b - std::sqrt(disc)) / a;
  if (t <= 1e-9 || t >= hit.t) return;
  hit.t = t;
  hit.normal = (oc + d * t) * (1.0 / s.radius);
  hit.kind = 1;
  hit.index = index;
}

void hit_box(const Box& b, int index, Vec3 o, Vec3 d, Hit& hit) {
  const double cy = b.cos_yaw, sy = b.sin_yaw;
  auto to_local = [&](Vec3 v) { return Vec3{cy * v.x - sy * v.z, v.y, sy * v.x + cy * v.z}; };
  Vec3 lo = to_local(o - b.center), ld = to_local(d);
  double t0 = -1e30, t1 = 1e30;
  int axis = -1;
  double sign = 0;
  const double h[3] = {b.half.x, b.half.y, b.half.z}, po[3] = {lo.x, lo.y, lo.z}, pd[3] = {ld.x, ld.y, ld.z};
  for (int k = 0; k < 3; ++k) {
    if (std::abs(pd[k]) < 1e-12) {
      if (std::abs(po[k]) > h[k]) return;
      continue;
    }
    double ta = (-h[k] - po[k]) / pd[k], tb = (h[k] - po[k]) / pd[k];
    double enter = std::min(ta, tb), exit = std::max(ta, tb);
    if (enter > t0) t0 = enter, axis = k, sign = pd[k] > 0 ? -1 : 1;
    t1 = std::min(t1, exit);
  }
  if (axis < 0 || t0 > t1 || t0 <= 1e-9 || t0 >= hit.t) return;
  Vec3 ln = {axis == 0 ? sign : 0, axis == 1 ? sign : 0, axis == 2 ? sign : 0};
  hit.t = t0;
  hit.normal = {cy * ln.x + sy * ln.z, ln.y, -sy * ln.x + cy * ln.z};  // back to world (inverse rotation)
  hit.kind = 2;
  hit.index = index;
  hit.local = lo + ld * t0;
  hit.axis = axis;
}

// Surface colour at the final hit (world point p).
Vec3 albedo_at(const Room& room, const Hit& hit, Vec3 p, double footprint) {
  if (hit.kind == 0) {
    if (hit.index < 4) return eval_texture(room.walls[hit.index], hit.index < 2 ? p.z : p.x, p.y, footprint);
    if (hit.index == 4) return eval_floor(room.floor, p.x, p.z, footprint);
    return eval_texture(room.ceiling, p.x, p.z, footprint);
  }
  if (hit.kind == 1) {
    // Arc-length coordinates on the sphere, so the pattern period is in metres like everywhere else.
    const Sphere& s = room.spheres[hit.index];
    Vec3 n = hit.normal;
    return eval_texture(s.tex, std::atan2(n.x, n.z) * s.radius, std::asin(std::clamp(n.y, -1.0, 1.0)) * s.radius,
                        footprint);
  }
  const Box& b = room.boxes[hit.index];
  Vec3 lp = hit.local;
  double u = hit.axis == 0 ? lp.z : lp.x, v = hit.axis == 1 ? lp.z : lp.y;
  return eval_texture(b.tex, u + hit.axis * 3.1, v, footprint);
}

// Colour (0..1) and z-depth of the surface through pixel centre (u+0.5, v+0.5).
Vec3 trace(const Room& room, const Camera& cam, double cx, double cy, int u, int v, float* depth) {
  Vec3 dc = {(u + 0.5 - cx) / room.fx, (v + 0.5 - cy) / room.fx, 1.0};
  // World direction with camera-z component 1, so the hit parameter t is the camera z-depth.
  Vec3 d = cam.axes[0] * dc.x + cam.axes[1] * dc.y + cam.axes[2] * dc.z;
  Hit hit;
  hit_room(room, cam.position, d, hit);
  for (size_t k = 0; k < room.spheres.size(); ++k) hit_sphere(room.spheres[k], static_cast<int>(k), cam.position, d, hit);
  for (size_t k = 0; k < room.boxes.size(); ++k) hit_box(room.boxes[k], static_cast<int>(k), cam.position, d, hit);
  // Pixel footprint on the surface: angular pixel size (1/fx rad) times distance, stretched at grazing incidence.
  double dist = hit.t * std::sqrt(dot(d, d));
  double cos_incidence = std::max(std::abs(dot(hit.normal, d)) / std::sqrt(dot(d, d)), 0.1);
  Vec3 albedo = albedo_at(room, hit, cam.position + d * hit.t, dist / room.fx / cos_incidence);
  *depth = static_cast<float>(hit.t);
  double lambert = std::max(0.0, -dot(hit.normal, room.light_dir));
  return albedo * (room.ambient + (1 - room.ambient) * lambert);
}

void render_frame(const Room& room, const Camera& cam, int height, int width, uint8_t* rgb, float* depth) {
  double cx = width / 2.0, cy = height / 2.0;
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      size_t i = static_cast<size_t>(v) * width + u;
      Vec3 c = trace(room, cam, cx, cy, u, v, &depth[i]);
      rgb[i * 3 + 0] = static_cast<uint8_t>(std::lround(std::clamp(c.x, 0.0, 1.0) * 255));
      rgb[i * 3 + 1] = static_cast<uint8_t>(std::lround(std::clamp(c.y, 0.0, 1.0) * 255));
      rgb[i * 3 + 2] = static_cast<uint8_t>(std::lround(std::clamp(c.z, 0.0, 1.0) * 255));
    }
  }
}

// c2w [4,4] in float64 from a camera.
torch::Tensor camera_c2w(const Camera& c) {
  auto m = torch::eye(4, torch::kFloat64);
  auto a = m.accessor<double, 2>();
  for (int k = 0; k < 3; ++k) {
    a[0][k] = c.axes[k].x;
    a[1][k] = c.axes[k].y;
    a[2][k] = c.axes[k].z;
  }
  a[0][3] = c.position.x, a[1][3] = c.position.y, a[2][3] = c.position.z;
  return m;
}

// One direction of context_overlap: share of a's pixels landing inside b.
double overlap_one_way(const torch::Tensor& depth_a, const torch::Tensor& k_a, const torch::Tensor& c2w_a,
                       const torch::Tensor& k_b, const torch::Tensor& c2w_b) {
  int64_t h = depth_a.size(0), w = depth_a.size(1);
  auto ka = k_a.to(torch::kFloat64), kb = k_b.to(torch::kFloat64);
  auto vs = torch::arange(h, torch::kFloat64).add(0.5).view({h, 1}).expand({h, w});
  auto us = torch::arange(w, torch::kFloat64).add(0.5).view({1, w}).expand({h, w});
  auto z = depth_a.to(torch::kFloat64);
  auto pts = torch::stack({(us - ka[2]) / ka[0] * z, (vs - ka[3]) / ka[1] * z, z, torch::ones_like(z)}, -1);
  auto a2b = torch::linalg_inv(c2w_b.to(torch::kFloat64)).matmul(c2w_a.to(torch::kFloat64));
  auto q = pts.view({-1, 4}).matmul(a2b.t());
  auto qz = q.select(1, 2);
  auto pu = q.select(1, 0) / qz * kb[0] + kb[2], pv = q.select(1, 1) / qz * kb[1] + kb[3];
  auto inside = (qz > 1e-6) & (pu >= 0) & (pu < w) & (pv >= 0) & (pv < h);
  return inside.to(torch::kFloat64).mean().item<double>();
}

// Evaluation views of a test scene: [f, f+gap] and three sorted targets strictly between.
std::optional<EvalEntry> eval_entry(const RoomRender& r, uint64_t seed, const RoomSceneOptions& opt) {
  int frames = opt.frames;
  int gap = opt.eval_gap > 0 ? opt.eval_gap : frames / 2;
  if (gap < 4 || gap > frames - 1) return std::nullopt;
  Rng rng(seed ^ 0xE7A1E7A1ull);
  int64_t f = rng.integer(0, frames - 1 - gap);
  std::vector<int64_t> interior;
  for (int64_t i = f + 1; i < f + gap; ++i) interior.push_back(i);
  for (int j = 0; j < 3; ++j) std::swap(interior[j], interior[rng.integer(j, static_cast<int64_t>(interior.size()) - 1)]);
  std::vector<int64_t> targets(interior.begin(), interior.begin() + 3);
  std::sort(targets.begin(), targets.end());
  EvalEntry e;
  e.key = r.scene.key;
  e.context = {f, f + gap};
  e.target = targets;
  e.overlap = std::round(context_overlap(r, f, f + gap) * 1e5) / 1e5;
  return e;
}

// Runs fn(i) for i in [0, n) on at::get_num_threads() std::threads (dynamic assignment; results do not depend on
// it). Not at::parallel_for: that is inline and only parallel when the caller is compiled with -fopenmp, which this
// project is not. Nested calls (a scene rendering its frames inside a parallel loop over scenes) run serially.
thread_local bool t_in_parallel = false;

void parallel_for_each(int64_t n, const std::function<void(int64_t)>& fn) {
  int workers = static_cast<int>(std::min<int64_t>(n, std::max(1, at::get_num_threads())));
  if (t_in_parallel || workers <= 1) {
    for (int64_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::atomic<int64_t> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto work = [&] {
    t_in_parallel = true;
    for (int64_t i; (i = next++) < n;) {
      try {
        fn(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        next = n;  // stop handing out work
      }
    }
    t_in_parallel = false;
  };
  std::vector<std::thread> threads;
  for (int w = 1; w < workers; ++w) threads.emplace_back(work);
  work();
  for (auto& t : threads) t.join();
  if (error) std::rethrow_exception(error);
}

void check_options(const RoomSceneOptions& opt) {
  if (opt.height < 2 || opt.width < 2 || opt.frames < 1 || !(opt.frame_spacing > 0) || !(opt.texture_scale > 0) ||
      opt.jpeg_quality < 1 || opt.jpeg_quality > 100)
    throw std::runtime_error(fmt::format("room scenes: bad options (height {}, width {}, frames {}, frame_spacing "
                                         "{}, texture_scale {}, jpeg_quality {})",
                                         opt.height, opt.width, opt.frames, opt.frame_spacing, opt.texture_scale,
                                         opt.jpeg_quality));
}

}  // namespace

std::string room_scene_key(uint64_t seed) { return fmt::format("{:016x}", splitmix64(seed ^ 0x5EED5EED5EEDull)); }

uint64_t builtin_scene_seed(uint64_t dataset_seed, int split, int64_t index) {
  // Two rounds of mixing over (seed, split, index): distinct triples give distinct seeds except with ~2^-64 odds
  // (write_builtin_dataset still checks keys are unique).
  return splitmix64(splitmix64(dataset_seed) ^ (static_cast<uint64_t>(split) << 62) ^ static_cast<uint64_t>(index));
}

RoomRender render_room(uint64_t seed, const RoomSceneOptions& opt) {
  check_options(opt);
  Room room = sample_room(seed, opt);
  const int n = opt.frames, h = opt.height, w = opt.width;
  RoomRender r;
  r.images = torch::empty({n, h, w, 3}, torch::kUInt8);
  r.depth = torch::empty({n, h, w}, torch::kFloat32);
  r.scene.images.resize(n);
  parallel_for_each(n, [&](int64_t i) {
    render_frame(room, room.cameras[i], h, w, r.images[i].data_ptr<uint8_t>(), r.depth[i].data_ptr<float>());
    auto bytes = io::encode_jpeg(r.images[i], opt.jpeg_quality);
    r.scene.images[i] = torch::from_blob(bytes.data(), {static_cast<int64_t>(bytes.size())}, torch::kUInt8).clone();
  });
  std::vector<torch::Tensor> c2w(n);
  for (int i = 0; i < n; ++i) c2w[i] = camera_c2w(room.cameras[i]);
  auto c2w64 = torch::stack(c2w);
  r.c2w = c2w64.to(torch::kFloat32);
  r.fxfycxcy = torch::tensor({room.fx, room.fx, w / 2.0, h / 2.0}, torch::kFloat64).repeat({n, 1});
  r.scene.key = room_scene_key(seed);
  r.scene.url = fmt::format("builtin://room/{}", seed);
  r.scene.timestamps = torch::arange(n, torch::kInt64) * 100000;
  r.scene.cameras = make_cameras18(r.fxfycxcy, torch::linalg_inv(c2w64), w, h);
  r.fxfycxcy = r.fxfycxcy.to(torch::kFloat32);
  return r;
}

RawScene render_room_scene(uint64_t seed, const RoomSceneOptions& opt) { return render_room(seed, opt).scene; }

double context_overlap(const RoomRender& r, int64_t a, int64_t b) {
  double ab = overlap_one_way(r.depth[a], r.fxfycxcy[a], r.c2w[a], r.fxfycxcy[b], r.c2w[b]);
  double ba = overlap_one_way(r.depth[b], r.fxfycxcy[b], r.c2w[b], r.fxfycxcy[a], r.c2w[a]);
  return 0.5 * (ab + ba);
}

void write_builtin_dataset(const std::string& root, int num_train, int num_test, uint64_t seed,
                           const RoomSceneOptions& opt, int scenes_per_chunk) {
  check_options(opt);
  if (num_train < 0 || num_test < 0 || scenes_per_chunk < 1)
    throw std::runtime_error(fmt::format("write_builtin_dataset: bad counts (train {}, test {}, per chunk {})",
                                         num_train, num_test, scenes_per_chunk));
  std::set<std::string> all_keys;
  std::vector<EvalEntry> evaluation;
  const std::pair<const char*, int> splits[2] = {{"train", num_train}, {"test", num_test}};
  for (int split = 0; split < 2; ++split) {
    const std::string dir = (std::filesystem::path(root) / splits[split].first).string();
    std::filesystem::create_directories(dir);
    std::map<std::string, std::string> index;
    const int count = splits[split].second;
    for (int first = 0, chunk = 0; first < count; first += scenes_per_chunk, ++chunk) {
      const int in_chunk = std::min(scenes_per_chunk, count - first);
      std::vector<RoomRender> renders(in_chunk);
      // Scenes in parallel (each renders its frames serially inside).
      parallel_for_each(in_chunk, [&](int64_t j) { renders[j] = render_room(builtin_scene_seed(seed, split, first + j), opt); });
      std::vector<RawScene> scenes;
      const std::string file = fmt::format("{:06d}.torch", chunk);
      for (int j = 0; j < in_chunk; ++j) {
        const auto& r = renders[j];
        if (!all_keys.insert(r.scene.key).second)
          throw std::runtime_error(fmt::format("write_builtin_dataset: duplicate scene key {}", r.scene.key));
        index[r.scene.key] = file;
        if (split == 1)
          if (auto e = eval_entry(r, builtin_scene_seed(seed, split, first + j), opt)) evaluation.push_back(*e);
        scenes.push_back(r.scene);
      }
      write_chunk((std::filesystem::path(dir) / file).string(), scenes);
    }
    write_chunk_index(dir, index);
  }
  if (num_test > 0 && evaluation.empty())
    spdlog::warn("write_builtin_dataset: {} frames per scene leave no room for evaluation views (gap {})", opt.frames,
                 opt.eval_gap > 0 ? opt.eval_gap : opt.frames / 2);
  write_eval_index((std::filesystem::path(root) / "evaluation_index.json").string(), evaluation);
}

}  // namespace uplvsm::data
