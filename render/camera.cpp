#include "render/camera.h"

#include <algorithm>
#include <cmath>

namespace triad::render {

namespace {

constexpr double kPi = 3.14159265358979323846;

Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec3 normalize(const Vec3& a) {
  const double n = std::sqrt(dot(a, a));
  return n > 0 ? Vec3{a[0] / n, a[1] / n, a[2] / n} : Vec3{0, 0, -1};
}

// Camera basis: right, up, back (the camera looks along -back).
struct Basis {
  Vec3 r, u, b;
};
Basis basis(const Camera& cam) {
  Basis k;
  k.b = normalize(sub(cam.eye, cam.target));
  Vec3 up{0, 1, 0};
  if (std::fabs(dot(up, k.b)) > 0.999) up = {0, 0, -1};  // looking straight down or up
  k.r = normalize(cross(up, k.b));
  k.u = cross(k.b, k.r);
  return k;
}

std::array<Vec3, 8> corners(const Box& box) {
  std::array<Vec3, 8> c;
  for (int i = 0; i < 8; ++i)
    c[size_t(i)] = {(i & 1) ? box.max[0] : box.min[0], (i & 2) ? box.max[1] : box.min[1],
                    (i & 4) ? box.max[2] : box.min[2]};
  return c;
}

}  // namespace

Camera autoCamera(const Box& domain, double aspect, double fov_deg) {
  const Vec3 centre{0.5 * (domain.min[0] + domain.max[0]), 0.5 * (domain.min[1] + domain.max[1]),
                    0.5 * (domain.min[2] + domain.max[2])};
  const Vec3 ext = sub(domain.max, domain.min);
  const double radius = std::max(0.5 * std::sqrt(dot(ext, ext)), 1e-6);
  const Vec3 dir = normalize({0.55, 0.45, 1.0});  // front right, above
  Camera cam;
  cam.target = centre;
  cam.fov_deg = fov_deg;
  const double tan_y = std::tan(0.5 * fov_deg * kPi / 180.0), tan_x = tan_y * aspect;
  // Largest normalised image coordinate of the corners seen from distance d
  // (infinite when a corner is behind the eye).
  auto extent = [&](double d) {
    Camera c = cam;
    c.eye = {centre[0] + dir[0] * d, centre[1] + dir[1] * d, centre[2] + dir[2] * d};
    const Basis k = basis(c);
    double m = 0;
    for (const Vec3& p : corners(domain)) {
      const Vec3 q = sub(p, c.eye);
      const double z = -dot(q, k.b);
      if (z <= 1e-9) return 1e30;
      m = std::max({m, std::fabs(dot(q, k.r)) / (z * tan_x), std::fabs(dot(q, k.u)) / (z * tan_y)});
    }
    return m;
  };
  // The bounding sphere fits at d_hi; shrink by bisection to where the corners
  // fill 90% of the half-image. extent() decreases with distance.
  double hi = radius / std::sin(std::atan(std::min(tan_x, tan_y))) * 1.05, lo = radius;
  while (extent(hi) > 0.9) hi *= 1.5;
  for (int it = 0; it < 60; ++it) {
    const double mid = 0.5 * (lo + hi);
    (extent(mid) > 0.9 ? lo : hi) = mid;
  }
  cam.eye = {centre[0] + dir[0] * hi, centre[1] + dir[1] * hi, centre[2] + dir[2] * hi};
  return cam;
}

CameraMatrices cameraMatrices(const Camera& cam, double aspect, const Box& scene) {
  CameraMatrices m;
  const Basis k = basis(cam);
  // View: rows are the basis vectors; column-major storage.
  const Vec3 e = cam.eye;
  const double t[3] = {-dot(k.r, e), -dot(k.u, e), -dot(k.b, e)};
  const Vec3 rows[3] = {k.r, k.u, k.b};
  m.view.fill(0.0f);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m.view[size_t(c * 4 + r)] = float(rows[r][size_t(c)]);
    m.view[size_t(12 + r)] = float(t[r]);
  }
  m.view[15] = 1.0f;
  // Clip planes from the distances of the scene box's corners along the view.
  double zmin = 1e300, zmax = 0;
  for (const Vec3& p : corners(scene)) {
    const double z = -dot(sub(p, e), k.b);
    zmin = std::min(zmin, z);
    zmax = std::max(zmax, z);
  }
  const Vec3 ext = sub(scene.max, scene.min);
  const double size = std::max(std::sqrt(dot(ext, ext)), 1e-6);
  m.far_plane = std::max(zmax * 1.01, size * 1e-3);
  m.near_plane = std::max(zmin * 0.99, m.far_plane * 1e-4);
  if (m.near_plane >= m.far_plane * 0.999) m.near_plane = m.far_plane * 1e-4;
  const double f = 1.0 / std::tan(0.5 * cam.fov_deg * kPi / 180.0);
  const double n = m.near_plane, fa = m.far_plane;
  m.proj.fill(0.0f);
  m.proj[0] = float(f / aspect);
  m.proj[5] = float(f);
  m.proj[10] = float((fa + n) / (n - fa));
  m.proj[11] = -1.0f;
  m.proj[14] = float(2.0 * fa * n / (n - fa));
  return m;
}

Projected project(const Camera& cam, int width, int height, const Vec3& p) {
  const Basis k = basis(cam);
  const Vec3 q = sub(p, cam.eye);
  const double z = -dot(q, k.b);
  const double tan_y = std::tan(0.5 * cam.fov_deg * kPi / 180.0);
  const double aspect = double(width) / height;
  Projected out;
  out.depth = z;
  if (std::fabs(z) < 1e-300) return out;
  const double nx = dot(q, k.r) / (z * tan_y * aspect), ny = dot(q, k.u) / (z * tan_y);
  out.x = (nx * 0.5 + 0.5) * width;
  out.y = (0.5 - ny * 0.5) * height;
  return out;
}

}  // namespace triad::render
