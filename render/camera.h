#pragma once
// The preview camera: a pinhole looking from `eye` at `target`, y up, with a
// vertical field of view; its matrices (OpenGL conventions, column-major) and
// the automatic camera that frames a domain box.
#include <array>

namespace triad::render {

using Vec3 = std::array<double, 3>;
using Mat4 = std::array<float, 16>;  // column-major, as glUniformMatrix4fv takes it

struct Camera {
  Vec3 eye{2, 1.5, 2};
  Vec3 target{0.5, 0.5, 0.5};
  double fov_deg = 40.0;  // vertical
};

struct Box {
  Vec3 min{0, 0, 0};
  Vec3 max{1, 1, 1};
};

// A camera looking at the centre of `domain` from the front right and above,
// at the distance where all 8 corners fall inside the central 90% of an image
// of the given aspect ratio (width / height).
Camera autoCamera(const Box& domain, double aspect, double fov_deg = 35.0);

// The view and projection of a camera for an image of `aspect`, with clip
// planes that enclose `scene` (the domain and the ground around it).
struct CameraMatrices {
  Mat4 view{};
  Mat4 proj{};
  double near_plane = 0.01, far_plane = 100.0;
};
CameraMatrices cameraMatrices(const Camera& cam, double aspect, const Box& scene);

// Where a world point lands in an image of width x height pixels: x to the
// right, y downwards from the top left corner (pixel centres at +0.5), and its
// distance in front of the camera (negative: behind it).
struct Projected {
  double x = 0, y = 0, depth = 0;
};
Projected project(const Camera& cam, int width, int height, const Vec3& p);

}  // namespace triad::render
