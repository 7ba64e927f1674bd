// What the built-in generators (rooms, objects) share to ray-cast their scenes: small vectors, a portable seeded
// RNG, procedural surface textures, and the textured primitives (spheres, yawed boxes) with their ray hits and
// surface colours. World axes follow the cameras (OpenCV): y points down.
#pragma once
#include <array>
#include <cmath>
#include <cstdint>
#include <random>

namespace uplvsm::data::synthetic {

// ---------------------------------------------------------------------------------------------------- vectors
struct Vec3 {
  double x = 0, y = 0, z = 0;
};
inline Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 operator*(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(Vec3 a, Vec3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
inline Vec3 normalize(Vec3 a) { return a * (1.0 / std::sqrt(dot(a, a))); }
inline Vec3 lerp(Vec3 a, Vec3 b, double t) { return a + (b - a) * t; }
inline double lerp1(double a, double b, double t) { return a + (b - a) * t; }
double smoothstep(double e0, double e1, double x);

// ---------------------------------------------------------------------------------------------------- random
uint64_t splitmix64(uint64_t x);

// Explicit formulas (not std:: distributions, whose output is implementation-defined) keep scenes identical
// across standard libraries.
struct Rng {
  std::mt19937_64 engine;
  explicit Rng(uint64_t seed) : engine(splitmix64(seed)) {}
  double uniform() { return static_cast<double>(engine() >> 11) * (1.0 / 9007199254740992.0); }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  int64_t integer(int64_t lo, int64_t hi);
};

// A colour from hue/saturation/value in [0,1].
Vec3 hsv(double h, double s, double v);

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

Texture random_texture(Rng& rng, double base_hue, double period_lo, double period_hi);

// Fades a pattern towards its mean once a pixel covers a good part of its feature size `scale`: a cheap
// pre-filter, so distant or grazing surfaces show no aliasing noise (there is one ray per pixel).
double fade_detail(double value, double mean, double scale, double footprint);

// `footprint`: approximate size (metres) of the pixel's footprint on the surface.
Vec3 eval_texture(const Texture& t, double u, double v, double footprint);

// A pinhole camera: centre and the columns of its c2w rotation (right, down, forward).
struct Camera {
  Vec3 position;
  std::array<Vec3, 3> axes;
};

// ---------------------------------------------------------------------------------------------------- primitives
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

// Nearest intersection so far; the texture is evaluated once, for the final hit only.
struct Hit {
  double t = 1e30;
  int kind = -1;   // 0 a generator's own surfaces (room walls), 1 sphere, 2 box
  int index = -1;  // surface or object index
  Vec3 normal;
  Vec3 local;    // box: hit point in the box frame
  int axis = 0;  // box: axis of the face hit
};

// Ray o + t d: updates `hit` when the primitive is hit nearer than hit.t (and at t > 0).
void hit_sphere(const Sphere& s, int index, Vec3 o, Vec3 d, Hit& hit);
void hit_box(const Box& b, int index, Vec3 o, Vec3 d, Hit& hit);

// Surface colour of a sphere or box at a hit on it; patterns are laid out in metres on the surface.
Vec3 sphere_albedo(const Sphere& s, const Hit& hit, double footprint);
Vec3 box_albedo(const Box& b, const Hit& hit, double footprint);

}  // namespace uplvsm::data::synthetic
