#pragma once
// Collision particles of rigid and volumetric elastic solids (coupling.md):
// voxel samples with a mass, a position and an outward unit normal, and the
// rigid mass properties they imply. Plain Eigen; the sampling of shapes
// (meshes through their signed distance field) lives in import/.
#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "sim/math.h"
#include "sim/scene_desc.h"

namespace triad {

struct CollisionSamples {
  std::vector<Vec3f> x;       // sample positions, world space
  std::vector<Vec3f> normal;  // outward unit normal (SDF gradient), interior samples too
  std::vector<float> phi;     // signed distance to the surface at the sample (negative inside)
  float mass_per_sample = 0;    // density * spacing^3 (uniform density)
  float volume_per_sample = 0;  // spacing^3
  double spacing = 0;           // lattice spacing h; each sample stands for a cube of side h
  size_t size() const { return x.size(); }
};

struct MassProperties {
  double mass = 0;
  Vec3d centre = Vec3d::Zero();     // centre of mass
  Mat3d inertia = Mat3d::Zero();    // inertia tensor about the centre of mass, world axes
};

// Uniform-density mass properties of the samples: each sample is a cube of
// side h and mass m, so besides the point-mass term m (|r|^2 I - r r^T) it
// adds its own inertia m h^2 / 6 on the diagonal. With that term a box
// whose faces lie on the sample cells' faces is exact at any resolution.
MassProperties computeMassProperties(const CollisionSamples& samples);

// A closed triangle surface, for caches and previews.
struct TriSurface {
  std::vector<Vec3f> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
};

// Centroid of the volume a closed surface bounds (the mean of its vertices
// if it bounds none).
Vec3d volumeCentroid(const TriSurface& surface);

// A solid's collision particles and its surface, world space at t = 0.
struct SolidSamples {
  CollisionSamples samples;
  TriSurface surface;
};

// Samples a rigid or elastic solid's shape (box, sphere or mesh) at uniform
// `density`, on the lattice of `spacing` aligned with the domain's corner.
// Provided by import/ (mesh files); throws InputError.
using SolidSampler = std::function<SolidSamples(const ShapeDesc& shape, const DomainDesc& domain,
                                                double density, double spacing)>;

// Signed distance from p to the box [lo, hi] and its outward normal (exact;
// inside: to the nearest face, whose normal it takes).
double boxDistance(const Vec3d& lo, const Vec3d& hi, const Vec3d& p, Vec3d* normal);

// Surfaces of the primitive shapes: a box's 12 triangles, a sphere as an
// icosphere of 1280 triangles (within 0.3% of the radius).
TriSurface primitiveSurface(const ShapeDesc& shape);

}  // namespace triad
