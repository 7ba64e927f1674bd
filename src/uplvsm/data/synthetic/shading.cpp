// Shared ray-casting pieces of the built-in generators; see shading.h.
#include "uplvsm/data/synthetic/shading.h"

#include <algorithm>

#include "uplvsm/data/view_sampler.h"

namespace uplvsm::data::synthetic {

double smoothstep(double e0, double e1, double x) {
  double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

uint64_t splitmix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

int64_t Rng::integer(int64_t lo, int64_t hi) { return uniform_int(engine, lo, hi); }

Vec3 hsv(double h, double s, double v) {
  h = (h - std::floor(h)) * 6.0;
  int i = static_cast<int>(h) % 6;
  double f = h - std::floor(h), p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
  const Vec3 table[6] = {{v, t, p}, {q, v, p}, {p, v, t}, {p, q, v}, {t, p, v}, {v, p, q}};
  return table[i];
}

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

double fade_detail(double value, double mean, double scale, double footprint) {
  return lerp1(value, mean, smoothstep(0.2 * scale, 0.6 * scale, footprint));
}

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

Vec3 sphere_albedo(const Sphere& s, const Hit& hit, double footprint) {
  // Arc-length coordinates on the sphere, so the pattern period is in metres like everywhere else.
  Vec3 n = hit.normal;
  return eval_texture(s.tex, std::atan2(n.x, n.z) * s.radius, std::asin(std::clamp(n.y, -1.0, 1.0)) * s.radius,
                      footprint);
}

Vec3 box_albedo(const Box& b, const Hit& hit, double footprint) {
  Vec3 lp = hit.local;
  double u = hit.axis == 0 ? lp.z : lp.x, v = hit.axis == 1 ? lp.z : lp.y;
  return eval_texture(b.tex, u + hit.axis * 3.1, v, footprint);
}

}  // namespace uplvsm::data::synthetic
