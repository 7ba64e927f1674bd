// Procedural indoor walkthroughs: scene sampling (room, textures, objects, camera path), the room's ray caster and
// its evaluation views. World axes follow the cameras (OpenCV): y points down, so the floor is at +floor_y.
#include "uplvsm/data/synthetic/room_scenes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <stdexcept>

#include <fmt/format.h>

namespace uplvsm::data {
namespace {

using namespace synthetic;

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
    for (const auto& q : pos)
      x0 = std::min(x0, q.x), x1 = std::max(x1, q.x), z0 = std::min(z0, q.z), z1 = std::max(z1, q.z);
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
      Texture tex =
          random_texture(rng, base_hue + rng.uniform(0.2, 0.8), size * 0.6 * texture_scale, size * 1.4 * texture_scale);
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

// Surface colour at the final hit (world point p).
Vec3 albedo_at(const Room& room, const Hit& hit, Vec3 p, double footprint) {
  if (hit.kind == 0) {
    if (hit.index < 4) return eval_texture(room.walls[hit.index], hit.index < 2 ? p.z : p.x, p.y, footprint);
    if (hit.index == 4) return eval_floor(room.floor, p.x, p.z, footprint);
    return eval_texture(room.ceiling, p.x, p.z, footprint);
  }
  if (hit.kind == 1) return sphere_albedo(room.spheres[hit.index], hit, footprint);
  return box_albedo(room.boxes[hit.index], hit, footprint);
}

// Colour (0..1) and z-depth of the surface through pixel centre (u+0.5, v+0.5).
Vec3 trace(const Room& room, const Camera& cam, double cx, double cy, int u, int v, float* depth) {
  Vec3 dc = {(u + 0.5 - cx) / room.fx, (v + 0.5 - cy) / room.fx, 1.0};
  // World direction with camera-z component 1, so the hit parameter t is the camera z-depth.
  Vec3 d = cam.axes[0] * dc.x + cam.axes[1] * dc.y + cam.axes[2] * dc.z;
  Hit hit;
  hit_room(room, cam.position, d, hit);
  for (size_t k = 0; k < room.spheres.size(); ++k)
    hit_sphere(room.spheres[k], static_cast<int>(k), cam.position, d, hit);
  for (size_t k = 0; k < room.boxes.size(); ++k) hit_box(room.boxes[k], static_cast<int>(k), cam.position, d, hit);
  // Pixel footprint on the surface: angular pixel size (1/fx rad) times distance, stretched at grazing incidence.
  double dist = hit.t * std::sqrt(dot(d, d));
  double cos_incidence = std::max(std::abs(dot(hit.normal, d)) / std::sqrt(dot(d, d)), 0.1);
  Vec3 albedo = albedo_at(room, hit, cam.position + d * hit.t, dist / room.fx / cos_incidence);
  *depth = static_cast<float>(hit.t);
  double lambert = std::max(0.0, -dot(hit.normal, room.light_dir));
  return albedo * (room.ambient + (1 - room.ambient) * lambert);
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
  for (int j = 0; j < 3; ++j)
    std::swap(interior[j], interior[rng.integer(j, static_cast<int64_t>(interior.size()) - 1)]);
  std::vector<int64_t> targets(interior.begin(), interior.begin() + 3);
  std::sort(targets.begin(), targets.end());
  EvalEntry e;
  e.key = r.scene.key;
  e.context = {f, f + gap};
  e.target = targets;
  e.overlap = std::round(context_overlap(r, f, f + gap) * 1e5) / 1e5;
  return e;
}

void check_options(const RoomSceneOptions& opt) {
  if (opt.height < 2 || opt.width < 2 || opt.frames < 1 || !(opt.frame_spacing > 0) || !(opt.texture_scale > 0) ||
      opt.jpeg_quality < 1 || opt.jpeg_quality > 100)
    throw std::runtime_error(
        fmt::format("room scenes: bad options (height {}, width {}, frames {}, frame_spacing "
                    "{}, texture_scale {}, jpeg_quality {})",
                    opt.height, opt.width, opt.frames, opt.frame_spacing, opt.texture_scale, opt.jpeg_quality));
}

}  // namespace

std::string room_scene_key(uint64_t seed) { return builtin_scene_key(seed); }

RoomRender render_room(uint64_t seed, const RoomSceneOptions& opt) {
  check_options(opt);
  Room room = sample_room(seed, opt);
  const double cx = opt.width / 2.0, cy = opt.height / 2.0;
  auto tracer = [&](const Camera& cam, int u, int v, float* depth) { return trace(room, cam, cx, cy, u, v, depth); };
  return render_scene(room.cameras, room.fx, opt.height, opt.width, opt.jpeg_quality, tracer, room_scene_key(seed),
                      fmt::format("builtin://room/{}", seed));
}

RawScene render_room_scene(uint64_t seed, const RoomSceneOptions& opt) { return render_room(seed, opt).scene; }

RoomRender render_room_at(uint64_t seed, const RoomSceneOptions& opt, const torch::Tensor& c2w) {
  check_options(opt);
  TORCH_CHECK(c2w.dim() == 3 && c2w.size(1) == 4 && c2w.size(2) == 4, "render_room_at: expected c2w [N, 4, 4], got ",
              c2w.sizes());
  Room room = sample_room(seed, opt);
  auto m = c2w.to(torch::kCPU, torch::kFloat64).contiguous();
  auto a = m.accessor<double, 3>();
  std::vector<Camera> cameras(static_cast<size_t>(m.size(0)));
  for (int64_t i = 0; i < m.size(0); ++i) {
    auto& cam = cameras[static_cast<size_t>(i)];
    cam.position = {a[i][0][3], a[i][1][3], a[i][2][3]};
    for (int k = 0; k < 3; ++k) cam.axes[k] = {a[i][0][k], a[i][1][k], a[i][2][k]};  // columns: x, y, z axes
  }
  const double cx = opt.width / 2.0, cy = opt.height / 2.0;
  auto tracer = [&](const Camera& cam, int u, int v, float* depth) { return trace(room, cam, cx, cy, u, v, depth); };
  return render_scene(cameras, room.fx, opt.height, opt.width, opt.jpeg_quality, tracer, room_scene_key(seed),
                      fmt::format("builtin://room/{}", seed));
}

std::optional<uint64_t> room_seed_from_url(const std::string& url) {
  const std::string prefix = "builtin://room/";
  if (url.rfind(prefix, 0) != 0 || url.size() == prefix.size()) return std::nullopt;
  uint64_t seed = 0;
  for (size_t i = prefix.size(); i < url.size(); ++i) {
    if (url[i] < '0' || url[i] > '9') return std::nullopt;
    seed = seed * 10 + static_cast<uint64_t>(url[i] - '0');
  }
  return seed;
}

RoomSceneOptions room_scene_options(const DatasetConfig& c) {
  RoomSceneOptions opt;
  opt.height = static_cast<int>(c.render_height);
  opt.width = static_cast<int>(c.render_width);
  opt.frames = static_cast<int>(c.frames_per_scene);
  opt.frame_spacing = c.frame_spacing;
  opt.texture_scale = c.texture_scale;
  opt.eval_gap = static_cast<int>(c.eval_gap);
  return opt;
}

SceneGenerator room_generator(const RoomSceneOptions& opt) {
  check_options(opt);
  SceneGenerator g;
  g.name = "rooms";
  g.ordered_views = true;
  g.render = [opt](uint64_t seed) { return render_room(seed, opt); };
  g.eval_entry = [opt](const SceneRender& r, uint64_t seed) { return eval_entry(r, seed, opt); };
  return g;
}

void write_builtin_dataset(const std::string& root, int num_train, int num_test, uint64_t seed,
                           const RoomSceneOptions& opt, int scenes_per_chunk) {
  write_generated_dataset(root, num_train, num_test, seed, room_generator(opt), scenes_per_chunk);
}

}  // namespace uplvsm::data
