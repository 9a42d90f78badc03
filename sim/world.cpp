#include "sim/world.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>

#include "sim/errors.h"
#include "sim/mpm/hydrostatic.h"
#include "sim/mpm/sampling.h"

namespace triad {

namespace {

std::string objectKey(const SceneDesc& scene, size_t i) {
  return scene.source_path + ": objects[" + std::to_string(i) + "]";
}

Vec3d toVec(const Vec3Desc& a) { return Vec3d(a[0], a[1], a[2]); }

// `shape`: the object's own when null (a mesh sequence passes its frame 0).
SolidSamples sampleSolid(const SceneDesc& scene, size_t i, const SolidSampler& sampler,
                         double density, const ShapeDesc* shape = nullptr) {
  const ObjectDesc& obj = scene.objects[i];
  if (!sampler)
    throw InputError(objectKey(scene, i), "solid objects need a solid sampler (import/)");
  // The object's own spacing, or half a cell: 8 samples per cell.
  const double spacing = obj.sample_spacing > 0.0 ? obj.sample_spacing : 0.5 * scene.domain.dx;
  SolidSamples s;
  try {
    s = sampler(shape ? *shape : obj.shape, scene.domain, density, spacing);
  } catch (const InputError& e) {
    if (!e.where().empty()) throw;
    throw InputError(objectKey(scene, i) + ".shape", e.what());
  }
  if (s.samples.size() == 0) {
    char h[32];
    std::snprintf(h, sizeof h, "%g", spacing);
    throw InputError(objectKey(scene, i) + ".shape",
                     std::string("the shape is thinner than the collision particle spacing ") + h +
                         " m everywhere: no sample falls inside it");
  }
  return s;
}

// A fixed box's faces that lie on (or beyond) a domain wall are no surface:
// material cannot reach them, and a sample near one must take its distance
// and normal from the box's other faces. Otherwise a plate spanning the
// domain wall to wall has normals along the wall next to it, and material
// sliding down the wall slips past the plate there.
void closeWallFaces(const ShapeDesc& shape, const DomainDesc& domain, CollisionSamples& s) {
  const auto* b = std::get_if<BoxDesc>(&shape);
  if (!b) return;
  Vec3d lo = toVec(b->min), hi = toVec(b->max);
  const double far = 1e3 * (toVec(domain.max) - toVec(domain.min)).maxCoeff();
  const double tol = 1e-9 * far;
  bool any = false;
  for (int d = 0; d < 3; ++d) {
    if (lo[d] <= domain.min[d] + tol) lo[d] = domain.min[d] - far, any = true;
    if (hi[d] >= domain.max[d] - tol) hi[d] = domain.max[d] + far, any = true;
  }
  if (!any) return;
  for (size_t q = 0; q < s.size(); ++q) {
    Vec3d n;
    s.phi[q] = float(boxDistance(lo, hi, s.x[q].cast<double>(), &n));
    s.normal[q] = n.cast<float>();
  }
}

// A body that spans the domain wall to wall along an axis can never leave
// either wall, so its faces there are no surface either, whatever its shape
// and whether or not it moves: material cannot reach them. Left as faces,
// they gave the samples within a few cells of the walls (all of them in a
// quasi-2D tank a few cells thick) normals along the wall, and the water's
// pressure at those nodes went into the walls: a 5-cell log spanning such
// a tank, held under water, felt 62% of its buoyancy (101% as a fixed box,
// whose faces were closed). Each sample whose normal lies along the wall's
// takes its distance and normal, measured across the axis, from the nearest
// surface point of the other faces: those of the boundary samples of its
// layer nearer to another face than to either wall, or of the nearest layer
// that has such samples (the layers next to a wall have none: their rim
// samples lie as near to the wall as to the side). The other samples keep
// their distance, their normals made to lie across the axis. Exact for a
// prism along the axis. Only the axes in `axes` are looked at. Returns the
// axes it closed.
SpannedWalls closeSpannedWalls(const DomainDesc& domain, CollisionSamples& s,
                               const std::array<bool, 3>& axes = {true, true, true}) {
  SpannedWalls walls{{false, false, false}, toVec(domain.min), toVec(domain.max)};
  if (s.size() == 0) return walls;
  const double h = s.spacing, tol = 1e-3 * h;
  for (int d = 0; d < 3; ++d) {
    if (!axes[size_t(d)]) continue;
    float lo = std::numeric_limits<float>::max(), hi = -lo;
    for (const Vec3f& x : s.x) lo = std::min(lo, x[d]), hi = std::max(hi, x[d]);
    if (lo - 0.5 * h > domain.min[d] + tol || hi + 0.5 * h < domain.max[d] - tol) continue;
    walls.axis[size_t(d)] = true;
    auto wallDistance = [&](size_t q) {
      return std::min(double(s.x[q][d]) - domain.min[d], domain.max[d] - double(s.x[q][d]));
    };
    // Layers along d, by lattice index, and each one's surface points.
    std::map<long, std::vector<size_t>> layers;
    for (size_t q = 0; q < s.size(); ++q)
      layers[std::lround((double(s.x[q][d]) - domain.min[d]) / h - 0.5)].push_back(q);
    std::map<long, std::vector<std::pair<Vec3f, Vec3f>>> surface;  // point, normal
    for (const auto& [layer, members] : layers)
      for (const size_t q : members) {
        if (s.phi[q] > -float(h) && std::abs(s.normal[q][d]) < 0.5f &&
            wallDistance(q) > -s.phi[q] + tol)
          surface[layer].push_back({s.x[q] - s.phi[q] * s.normal[q], s.normal[q]});
      }
    if (surface.empty()) continue;
    for (const auto& [layer, members] : layers) {
      // This layer's points, or the nearest layer's (surface is not empty).
      auto it = surface.lower_bound(layer);
      if (it == surface.end() || (it->first != layer && it != surface.begin() &&
                                  layer - std::prev(it)->first < it->first - layer))
        --it;
      const auto& points = it->second;
      for (const size_t q : members) {
        if (std::abs(s.normal[q][d]) < 0.5f) {
          // The other samples keep their distance and lose their normal's
          // lean along the axis (a prism's faces have none). The samples
          // within a couple of spacings of a wall leaned by up to 0.4
          // towards it, from the faces there: their planes put points
          // between them and the wall outside the body, so the particles
          // that crept in there along an oblique face were never pushed
          // out (a log tilted 10 degrees, held under water in a quasi-2D
          // tank, lost half its buoyancy in 4 s). One as near to the wall
          // as to a side took its distance from the edge between them:
          // across the axis the side is |n across| of it away.
          Vec3f n = s.normal[q];
          n[d] = 0.0f;
          if (n.norm() > 0.0f) {
            if (wallDistance(q) <= -s.phi[q] + tol) s.phi[q] *= n.norm();
            s.normal[q] = n.normalized();
          }
          continue;
        }
        float best = std::numeric_limits<float>::max();
        size_t k = 0;
        for (size_t p = 0; p < points.size(); ++p) {
          Vec3f r = s.x[q] - points[p].first;
          r[d] = 0.0f;
          if (r.squaredNorm() < best) best = r.squaredNorm(), k = p;
        }
        // The distance to the nearest point's tangent plane, not to the
        // point (the points lie a spacing apart along the face: on a face
        // oblique to the lattice the nearest is up to half a spacing off
        // the sample's foot), and its normal across the axis only (rim
        // samples near the ends lean along it). A round log held under
        // water in a quasi-2D tank felt 82.5% of its buoyancy before, 89%
        // after (102% once the kept samples above lost their lean too).
        Vec3f n = points[k].second;
        n[d] = 0.0f;
        n = n.norm() > 0.0f ? Vec3f(n.normalized()) : Vec3f(points[k].second);
        Vec3f r = s.x[q] - points[k].first;
        r[d] = 0.0f;
        s.phi[q] = std::min(0.0f, r.dot(n));
        s.normal[q] = n;
      }
    }
  }
  return walls;
}

RigidBody buildRigidBody(const SceneDesc& scene, size_t i, const SolidSampler& sampler) {
  const ObjectDesc& obj = scene.objects[i];
  SolidSamples s = sampleSolid(scene, i, sampler, obj.density);
  if (obj.fixed) closeWallFaces(obj.shape, scene.domain, s.samples);
  closeSpannedWalls(scene.domain, s.samples);
  return makeRigidBody(int(i), obj.name, s.samples, std::move(s.surface), obj.fixed, obj.friction,
                       toVec(obj.velocity), toVec(obj.angular_velocity), scene.domain.dx);
}

// The axes along which an animation never moves a shape: no key translates
// along the axis or turns about another axis (the poses between keys turn
// about the keys' common axis too). A collider spanning the domain along
// such an axis (a wave maker's paddle in a flume) spans it all the time.
std::array<bool, 3> axesKept(const AnimationDesc& a) {
  std::array<bool, 3> kept{true, true, true};
  for (const AnimationKeyDesc& k : a.keys)
    for (size_t d = 0; d < 3; ++d) {
      if (k.translate[d] != 0.0) kept[d] = false;
      for (size_t e = 0; e < 3; ++e)
        if (e != d && k.rotate_deg[e] != 0.0) kept[d] = false;
    }
  return kept;
}

// A collider: a body of infinite mass whose reference point is the shape's
// centroid as written, moved by its animation if it has one (else it is a
// fixed body, scattered into the grid once).
RigidBody buildCollider(const SceneDesc& scene, size_t i, const SolidSampler& sampler,
                        const SequenceLoader& sequences) {
  const ObjectDesc& obj = scene.objects[i];
  // A mesh sequence is sampled at its frame 0.
  const auto* mesh = std::get_if<MeshDesc>(&obj.shape);
  std::optional<MeshFrames> frames;
  if (mesh && mesh->sequence_digits > 0) {
    if (!sequences)
      throw InputError(objectKey(scene, i) + ".shape.mesh.path",
                       "mesh sequences need a sequence loader (import/)");
    frames = sequences(*mesh, scene.frames.count);
  }
  // The samples' mass only weighs the velocity of nodes the collider shares
  // with other solids; any density does.
  const ShapeDesc first = frames ? ShapeDesc(frames->first) : obj.shape;
  SolidSamples s = sampleSolid(scene, i, sampler, 1000.0, &first);
  const bool animated = obj.animation.has_value() || frames.has_value();
  if (!animated) {
    closeWallFaces(obj.shape, scene.domain, s.samples);
    closeSpannedWalls(scene.domain, s.samples);
  } else if (!frames) {
    closeSpannedWalls(scene.domain, s.samples, axesKept(*obj.animation));
  }
  const Vec3d pivot = volumeCentroid(s.surface);
  RigidBody b = makeRigidBody(int(i), obj.name, s.samples, std::move(s.surface), true,
                              obj.friction, Vec3d::Zero(), Vec3d::Zero(), scene.domain.dx);
  b.collider = true;
  recentre(b, pivot);
  b.pivot = pivot;
  b.rest_principal = b.state.q_principal;
  if (frames) {
    // Bind the kept samples (world positions at t = 0) to the surface.
    const Mat3d P = b.principal.toRotationMatrix();
    std::vector<Vec3f> x, n;
    for (size_t q = 0; q < b.r.size(); ++q) {
      x.push_back((pivot + P * b.r[q].cast<double>()).cast<float>());
      n.push_back((P * b.n[q].cast<double>()).cast<float>());
    }
    const double reach = (kCouplingDepth + 1.0) * scene.domain.dx + b.spacing;
    b.deform = std::make_shared<DeformingSurface>(std::move(frames->positions), frames->triangles,
                                                  scene.frames.fps, x, n, reach);
  }
  if (animated) {
    b.animated = true;
    if (obj.animation) b.animation = Animation(*obj.animation);
    b.poseAt(0.0);
  }
  return b;
}

ElasticSolid buildElasticSolid(const SceneDesc& scene, size_t i, const SolidSampler& sampler) {
  const ObjectDesc& obj = scene.objects[i];
  const MaterialDesc& m = scene.materials[size_t(obj.material)];
  SolidSamples s = sampleSolid(scene, i, sampler, m.density);
  // A solid spanning the domain keeps to the walls too: no surface there,
  // as for rigid bodies. (One that shrank across the tank would open a
  // gap there that material could enter; the walls' pressure on a solid
  // under water squeezes it against them instead.)
  const SpannedWalls walls = closeSpannedWalls(scene.domain, s.samples);
  try {
    ElasticSolid e = makeElasticSolid(int(i), obj.name, s.samples, std::move(s.surface), m,
                                      obj.friction, toVec(obj.velocity), walls);
    e.implicit = obj.integrator == ElasticIntegrator::Implicit;
    e.fem.damping = obj.damping;
    return e;
  } catch (const InputError& e) {
    throw InputError(objectKey(scene, i) + ".material", e.what());
  }
}

// The centroid of a primitive as written; of a mesh, the mean of its samples.
Vec3d shapeCentroid(const ShapeDesc& shape, const std::vector<Vec3f>& samples) {
  if (const auto* b = std::get_if<BoxDesc>(&shape)) return 0.5 * (toVec(b->min) + toVec(b->max));
  if (const auto* s = std::get_if<SphereDesc>(&shape)) return toVec(s->center);
  Vec3d m = Vec3d::Zero();
  for (const Vec3f& p : samples) m += p.cast<double>();
  return samples.empty() ? m : Vec3d(m / double(samples.size()));
}

Sink buildSink(const SceneDesc& scene, size_t i, const SolidSampler& sampler) {
  const ObjectDesc& obj = scene.objects[i];
  Sink k;
  k.object = int(i);
  k.name = obj.name;
  k.shape = obj.shape;
  std::vector<Vec3f> points;
  if (std::holds_alternative<MeshDesc>(obj.shape)) {
    // Inside the mesh: the cells of a half-cell lattice that hold a sample.
    SolidSamples s = sampleSolid(scene, i, sampler, 1000.0);
    points = s.samples.x;
    k.h = s.samples.spacing;
    Vec3d lo = Vec3d::Constant(1e300), hi = -lo;
    for (const Vec3f& p : points) {
      lo = lo.cwiseMin(p.cast<double>());
      hi = hi.cwiseMax(p.cast<double>());
    }
    k.lattice_lo = lo;
    for (int d = 0; d < 3; ++d) k.dims[d] = int(std::lround((hi[d] - lo[d]) / k.h)) + 1;
    k.inside.assign(size_t(k.dims.prod()), 0);
    for (const Vec3f& p : points) {
      Eigen::Vector3i c;
      for (int d = 0; d < 3; ++d) c[d] = int(std::lround((p[d] - lo[d]) / k.h));
      k.inside[(size_t(c.x()) * k.dims.y() + c.y()) * k.dims.z() + c.z()] = 1;
    }
  }
  if (obj.animation) k.placement.animation = Animation(*obj.animation);
  k.placement.pivot = shapeCentroid(obj.shape, points);
  return k;
}

}  // namespace

size_t World::particleCount() const {
  size_t n = 0;
  for (const ParticleSet& s : sets) n += s.size();
  return n;
}

size_t World::particleBytes() const {
  size_t n = 0;
  for (const ParticleSet& s : sets) n += s.bytes();
  return n;
}

World buildWorld(const SceneDesc& scene, const MeshSampler& mesh_sampler,
                 const SolidSampler& solid_sampler, const SequenceLoader& sequence_loader,
                 ParticleShare* share) {
  World world;
  world.scene = scene;
  world.object_particles.assign(scene.objects.size(), 0);
  const DomainDesc& domain = scene.domain;
  // Block keys hold 21 bits per axis: about four million cells.
  for (int d = 0; d < 3; ++d) {
    if ((domain.max[d] - domain.min[d]) / domain.dx > double(1 << 22))
      throw InputError(scene.source_path + ": domain.dx",
                       "the domain spans more than 4194304 cells along an axis");
  }
  if (scene.objects.size() > std::numeric_limits<uint16_t>::max())
    throw InputError(scene.source_path + ": objects", "at most 65535 objects are supported");

  const int ppc = scene.solver.particles_per_cell;
  const double volume = std::pow(domain.dx, 3) / ppc;
  std::map<int, size_t> set_of_material;
  uint32_t next_id = 0;
  // With a share, each MPM object's positions, made into particles once
  // every object is sampled: the share is cut from all of them.
  struct Sampled {
    size_t set;
    std::vector<Vec3f> points;
    Vec3f vel;
    uint32_t first_id;
    uint16_t object;
  };
  std::vector<Sampled> sampled;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const ObjectDesc& obj = scene.objects[i];
    if (obj.kind == ObjectKind::Elastic) {
      world.elastics.push_back(buildElasticSolid(scene, i, solid_sampler));
      world.object_particles[i] = world.elastics.back().fem.nodes();
      continue;
    }
    if (obj.kind == ObjectKind::Rigid || obj.kind == ObjectKind::Collider) {
      world.bodies.push_back(obj.kind == ObjectKind::Rigid
                                 ? buildRigidBody(scene, i, solid_sampler)
                                 : buildCollider(scene, i, solid_sampler, sequence_loader));
      world.object_particles[i] = world.bodies.back().r.size();
      continue;
    }
    if (obj.kind == ObjectKind::Sink) {
      world.sinks.push_back(buildSink(scene, i, solid_sampler));
      continue;
    }
    std::vector<Vec3f> points;
    try {
      points = sampleShape(obj.shape, domain, ppc, mesh_sampler);
    } catch (const InputError& e) {
      // The sampler names the mesh file itself; primitives get the key path.
      if (!e.where().empty()) throw;
      throw InputError(objectKey(scene, i) + ".shape", e.what());
    }
    if (points.empty())
      throw InputError(objectKey(scene, i) + ".shape",
                       "the shape holds no particle inside the domain at this dx and "
                       "particles_per_cell");
    if (double(next_id) + double(points.size()) > double(std::numeric_limits<uint32_t>::max()))
      throw InputError(objectKey(scene, i), "more than 2^32 particles");

    // One set per material: the material is visited once per set.
    auto [it, inserted] = set_of_material.try_emplace(obj.material, world.sets.size());
    if (inserted) {
      const MaterialDesc& m = scene.materials[obj.material];
      ParticleSet set;
      set.material = obj.material;
      set.model = makeMaterial(m);
      set.volume = static_cast<float>(volume);
      set.mass = static_cast<float>(volume * m.density);
      world.sets.push_back(std::move(set));
    }
    if (obj.emit) {
      // A source holds no particles before it starts: its points are sites.
      const Vec3d pivot = shapeCentroid(obj.shape, points);
      world.sources.push_back(
          makeSource(int(i), obj, it->second, std::move(points), domain, ppc, pivot));
      continue;
    }
    const Vec3f vel(float(obj.velocity[0]), float(obj.velocity[1]), float(obj.velocity[2]));
    world.object_particles[i] = points.size();
    world.whole_particles += points.size();
    if (share) {
      sampled.push_back({it->second, std::move(points), vel, next_id, static_cast<uint16_t>(i)});
      next_id += uint32_t(sampled.back().points.size());
      continue;
    }
    // Exact capacity: grown by doubling, the arrays held a fifth more than
    // the particles (21 bytes per particle on the 216k jelly cube).
    ParticleSet& set = world.sets[it->second];
    set.reserve(set.size() + points.size());
    for (const Vec3f& p : points) set.push(p, vel, next_id++, static_cast<uint16_t>(i));
  }
  world.next_id = next_id;

  // Water that starts at rest under its own weight: its levels from every
  // water particle the objects made (not the sources': they start moving).
  const bool hydrostatic = std::any_of(
      scene.objects.begin(), scene.objects.end(),
      [](const ObjectDesc& o) { return o.initial_pressure == InitialPressure::Hydrostatic; });
  std::optional<WaterLevels> levels;
  if (hydrostatic) {
    levels.emplace(domain, Vec3d(scene.gravity[0], scene.gravity[1], scene.gravity[2]),
                   domain.dx / std::cbrt(double(ppc)));
    const auto isWater = [&](size_t set) {
      return std::holds_alternative<Water<float>>(world.sets[set].model);
    };
    for (size_t k = 0; k < world.sets.size(); ++k)
      if (isWater(k))
        for (const Vec3f& x : world.sets[k].x) levels->add(x);
    for (const Sampled& o : sampled)
      if (isWater(o.set))
        for (const Vec3f& x : o.points) levels->add(x);
    levels->finish();
  }

  // Sources that start at once are full in the first frame.
  if (!share) {
    if (levels) startHydrostatic(world, *levels);
    world.whole_particles += emitFromSources(world.sources, world.sets, domain, 0.0, world.next_id);
    return world;
  }
  // A share is cut from every position, the sources' first particles too
  // (made into empty copies of the sets: a source's survey of its sites
  // counts only its own particles); then only what it keeps is built, each
  // particle with its place in the whole world's set.
  std::vector<ParticleSet> emitted = world.sets;
  world.whole_particles += emitFromSources(world.sources, emitted, domain, 0.0, world.next_id);
  std::vector<const std::vector<Vec3f>*> positions;
  for (const Sampled& o : sampled) positions.push_back(&o.points);
  for (const ParticleSet& e : emitted) positions.push_back(&e.x);
  share->plan(positions);
  // Which particles are kept, decided once (objects, then sources, as in
  // `positions`), counted per set for exact capacity.
  std::vector<std::vector<uint8_t>> keep(positions.size());
  std::vector<size_t> kept(world.sets.size(), 0);
  for (size_t o = 0; o < positions.size(); ++o) {
    const size_t k = o < sampled.size() ? sampled[o].set : o - sampled.size();
    keep[o].resize(positions[o]->size());
    for (size_t j = 0; j < keep[o].size(); ++j)
      kept[k] += keep[o][j] = share->keeps((*positions[o])[j]);
  }
  world.share_index.assign(world.sets.size(), {});
  for (size_t k = 0; k < world.sets.size(); ++k) {
    world.sets[k].reserve(kept[k]);
    world.share_index[k].reserve(kept[k]);
  }
  std::vector<uint64_t> whole_count(world.sets.size(), 0);
  for (size_t o = 0; o < sampled.size(); ++o) {
    Sampled& s = sampled[o];
    ParticleSet& set = world.sets[s.set];
    for (size_t j = 0; j < s.points.size(); ++j, ++whole_count[s.set]) {
      if (!keep[o][j]) continue;
      set.push(s.points[j], s.vel, s.first_id + uint32_t(j), s.object);
      world.share_index[s.set].push_back(whole_count[s.set]);
    }
    s.points = std::vector<Vec3f>();  // given back object by object
  }
  for (size_t k = 0; k < world.sets.size(); ++k) {
    const ParticleSet& e = emitted[k];
    const std::vector<uint8_t>& keep_e = keep[sampled.size() + k];
    for (size_t i = 0; i < e.size(); ++i) {
      if (!keep_e[i]) continue;
      world.sets[k].push(e.x[i], e.v[i], e.id[i], e.object[i]);
      world.share_index[k].push_back(whole_count[k] + i);
    }
  }
  if (levels) startHydrostatic(world, *levels);
  return world;
}

}  // namespace triad
