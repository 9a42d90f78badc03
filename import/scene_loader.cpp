#include "import/scene_loader.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <map>

#include <nlohmann/json.hpp>

#include "import/param_dict.h"
#include "sim/errors.h"

namespace triad {

namespace fs = std::filesystem;

namespace {

// The sparse grid packs block coordinates into 21 bits per axis, and the
// particle cache stores object ids in 16 bits (World::build checks both
// again); rejecting a domain or a scene too large for them here also turns
// an accidental dx of 1e-9 into an input error rather than a late failure.
constexpr double kMaxCellsPerAxis = 1 << 22;
constexpr std::size_t kMaxObjects = 65535;
constexpr int kMinCellsPerAxis = 4;

const ParamDict::Choices<BoundaryType> kBoundaryTypes = {{"slip", BoundaryType::Slip},
                                                         {"sticky", BoundaryType::Sticky},
                                                         {"separate", BoundaryType::Separate}};
const ParamDict::Choices<TransferScheme> kTransfers = {
    {"apic", TransferScheme::Apic}, {"pic", TransferScheme::Pic}, {"flip", TransferScheme::Flip}};
const ParamDict::Choices<CouplingScheme> kCouplings = {{"three_grid", CouplingScheme::ThreeGrid},
                                                       {"single_grid", CouplingScheme::SingleGrid}};
const ParamDict::Choices<ContactVelocity> kContactVelocities = {
    {"after_update", ContactVelocity::AfterUpdate}, {"before_update", ContactVelocity::BeforeUpdate}};
const ParamDict::Choices<SolidReadback> kReadbacks = {
    {"momentum_conserving", SolidReadback::MomentumConserving},
    {"combined", SolidReadback::Combined}};
const ParamDict::Choices<InitialPressure> kInitialPressures = {
    {"none", InitialPressure::None}, {"hydrostatic", InitialPressure::Hydrostatic}};
const ParamDict::Choices<ElasticIntegrator> kIntegrators = {
    {"explicit", ElasticIntegrator::Explicit}, {"implicit", ElasticIntegrator::Implicit}};
const ParamDict::Choices<RigidNodeMass> kNodeMasses = {{"body_share", RigidNodeMass::BodyShare},
                                                        {"node", RigidNodeMass::Node}};
const ParamDict::Choices<RigidNodeVelocity> kNodeVelocities = {
    {"body", RigidNodeVelocity::Body}, {"samples", RigidNodeVelocity::Samples}};
const ParamDict::Choices<ContactNormal> kContactNormals = {{"samples", ContactNormal::Samples},
                                                           {"distance", ContactNormal::Distance}};
const ParamDict::Choices<RigidCollision> kRigidCollisions = {{"jacobi", RigidCollision::Jacobi},
                                                             {"newton", RigidCollision::Newton}};
const ParamDict::Choices<MaterialModel> kModels = {
    {"fixed_corotated", MaterialModel::FixedCorotated},
    {"neo_hookean", MaterialModel::NeoHookean},
    {"snow", MaterialModel::Snow},
    {"drucker_prager", MaterialModel::DruckerPrager},
    {"mohr_coulomb", MaterialModel::MohrCoulomb},
    {"water", MaterialModel::Water}};
const ParamDict::Choices<ObjectKind> kKinds = {{"mpm", ObjectKind::Mpm},
                                               {"rigid", ObjectKind::Rigid},
                                               {"elastic", ObjectKind::Elastic},
                                               {"collider", ObjectKind::Collider},
                                               {"sink", ObjectKind::Sink}};
const ParamDict::Choices<Interpolation> kInterpolations = {{"linear", Interpolation::Linear},
                                                           {"smooth", Interpolation::Smooth}};

template <class E>
std::string nameOf(const ParamDict::Choices<E>& choices, E value) {
  for (const auto& c : choices) {
    if (c.second == value) return c.first;
  }
  return "?";
}

std::string inQuotes(const std::string& s) {
  return "\"" + s + "\"";
}

std::string vecString(const Vec3Desc& v) {
  return "[" + formatNumber(v[0]) + ", " + formatNumber(v[1]) + ", " + formatNumber(v[2]) + "]";
}

// Names become file and directory names (out/<name>, bodies/<name>.FFFF.ply),
// so they are kept to characters that are safe on every file system.
bool isSafeName(const std::string& s) {
  if (s.empty() || s == "." || s == "..") return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '.' || c == '-';
  });
}

std::string requireSafeName(const ParamDict& d, const std::string& key) {
  const std::string name = d.requireString(key);
  if (!isSafeName(name)) {
    d.fail(key,
           "expected a name of the characters A-Z a-z 0-9 _ . - (it names output files), got " +
               inQuotes(name));
  }
  return name;
}

// Relative paths in a scene are relative to the scene file's directory.
std::string resolveRelative(const std::string& scene_dir, const std::string& p) {
  const fs::path path(p);
  if (path.is_absolute() || scene_dir.empty()) return path.lexically_normal().string();
  return (fs::path(scene_dir) / path).lexically_normal().string();
}

// Check that every component of `max` exceeds that of `min` (both read from d).
void requireOrdered(const ParamDict& d, const Vec3Desc& min, const Vec3Desc& max) {
  for (int a = 0; a < 3; ++a) {
    if (!(max[a] > min[a])) {
      d.fail("max", "expected every component greater than min's " + vecString(min) + ", got " +
                        vecString(max));
    }
  }
}

// Sections

FramesDesc parseFrames(const ParamDict& root) {
  FramesDesc out;
  if (auto f = root.getDict("frames")) {
    out.count = f->getInt("count", out.count, Range::nonNegative());
    out.fps = f->getDouble("fps", out.fps, Range::positive());
    f->checkUnknownKeys();
  }
  return out;
}

DomainDesc parseDomain(const ParamDict& root) {
  const ParamDict d = root.requireDict("domain");
  DomainDesc out;
  out.min = d.requireVec3("min");
  out.max = d.requireVec3("max");
  requireOrdered(d, out.min, out.max);
  out.dx = d.requireDouble("dx", Range::positive());

  // Check the grid resolution the spacing implies
  const char* axes = "xyz";
  for (int a = 0; a < 3; ++a) {
    const double extent = out.max[a] - out.min[a];
    const double cells = extent / out.dx;
    if (cells < kMinCellsPerAxis * (1 - 1e-9)) {
      d.fail("dx", "expected at most " + formatNumber(extent / kMinCellsPerAxis) +
                       " so that the domain spans at least 4 cells along " + axes[a] + ", got " +
                       formatNumber(out.dx) + " (" + formatNumber(cells) + " cells)");
    }
    if (cells > kMaxCellsPerAxis) {
      d.fail("dx", "expected at least " + formatNumber(extent / kMaxCellsPerAxis) +
                       " so that the domain spans at most " + formatNumber(kMaxCellsPerAxis) +
                       " cells along " + axes[a] + ", got " + formatNumber(out.dx));
    }
  }

  if (auto b = d.getDict("boundary")) {
    out.boundary.type = b->getEnum("type", out.boundary.type, kBoundaryTypes);
    out.boundary.friction = b->getDouble("friction", out.boundary.friction, Range::nonNegative());
    b->checkUnknownKeys();
  }
  d.checkUnknownKeys();
  return out;
}

SolverDesc parseSolver(const ParamDict& root) {
  SolverDesc out;
  auto s = root.getDict("solver");
  if (!s) return out;
  out.cfl = s->getDouble("cfl", out.cfl, Range::openClosed(0, 1));
  out.max_dt = s->getDouble("max_dt", out.max_dt, Range::positive());
  out.particles_per_cell =
      s->getInt("particles_per_cell", out.particles_per_cell, Range::closed(1, 64));
  out.transfer = s->getEnum("transfer", out.transfer, kTransfers);
  // A blend ratio under another scheme would be silently ignored: reject it.
  if (out.transfer == TransferScheme::Flip) {
    out.flip_ratio = s->getDouble("flip_ratio", out.flip_ratio, Range::closed(0, 1));
  }
  out.coupling = s->getEnum("coupling", out.coupling, kCouplings);
  if (out.coupling == CouplingScheme::ThreeGrid) {
    out.contact_reach = s->getDouble("contact_reach", out.contact_reach, Range::closed(0, 1.5));
    out.contact_normal = s->getEnum("contact_normal", out.contact_normal, kContactNormals);
    out.rigid_collision = s->getEnum("rigid_collision", out.rigid_collision, kRigidCollisions);
    out.contact_gap = s->getBool("contact_gap", out.contact_gap);
    out.contact_gap_fixed = s->getBool("contact_gap_fixed", out.contact_gap_fixed);
    out.front_fields = s->getBool("front_fields", out.front_fields);
    out.elastic_contact_passes =
        s->getInt("elastic_contact_passes", out.elastic_contact_passes, Range::closed(0, 100));
    // Each particle gathers its own field's velocity and affine part: APIC's.
    if (out.front_fields && out.transfer != TransferScheme::Apic)
      s->fail("front_fields", "applies only with transfer \"apic\", and transfer is " +
                                  inQuotes(nameOf(kTransfers, out.transfer)));
    out.front_angle_deg =
        s->getDouble("front_angle_deg", out.front_angle_deg, Range::closed(0, 90));
  }
  out.contact_velocity = s->getEnum("contact_velocity", out.contact_velocity, kContactVelocities);
  out.solid_readback = s->getEnum("solid_readback", out.solid_readback, kReadbacks);
  out.rigid_node_mass = s->getEnum("rigid_node_mass", out.rigid_node_mass, kNodeMasses);
  out.rigid_node_velocity =
      s->getEnum("rigid_node_velocity", out.rigid_node_velocity, kNodeVelocities);
  out.coupling_iterations =
      s->getInt("coupling_iterations", out.coupling_iterations, Range::closed(1, 1000));
  out.contact_iterations =
      s->getInt("contact_iterations", out.contact_iterations, Range::closed(1, 1000));
  // Settled material sleeps: true (the measured defaults), false, or the
  // speed threshold, delay and whether neighbours must be still too.
  if (const nlohmann::json* sleep = s->find("sleep")) {
    if (sleep->is_object()) {
      const ParamDict d = *s->getDict("sleep");
      out.sleep.enabled = true;
      out.sleep.speed = d.getDouble("speed", out.sleep.speed, Range::positive());
      out.sleep.delay = d.getDouble("delay", out.sleep.delay, Range::nonNegative());
      out.sleep.neighbours = d.getBool("neighbours", out.sleep.neighbours);
      d.checkUnknownKeys();
    } else {
      out.sleep.enabled = s->getBool("sleep", false);
    }
  }
  s->checkUnknownKeys({}, [&](const std::string& key) -> std::string {
    if (key == "contact_reach" || key == "contact_normal" || key == "rigid_collision" ||
        key == "contact_gap" || key == "contact_gap_fixed" || key == "front_fields" ||
        key == "elastic_contact_passes" || key == "front_angle_deg")
      return std::string("it applies only when coupling is \"three_grid\", and coupling is ") +
             inQuotes(nameOf(kCouplings, out.coupling));
    if (key != "flip_ratio") return {};
    return "it applies only when transfer is \"flip\", and transfer is " +
           inQuotes(nameOf(kTransfers, out.transfer));
  });
  return out;
}

// Which models take a parameter, for the message when another model is given it.
std::string materialKeyHint(const std::string& key) {
  std::string owner;
  if (key == "youngs_modulus" || key == "poisson_ratio") {
    owner = "fixed_corotated, neo_hookean, snow, drucker_prager and mohr_coulomb";
  } else if (key == "critical_compression" || key == "critical_stretch" || key == "hardening") {
    owner = "snow";
  } else if (key == "friction_angle_deg" || key == "cohesion") {
    owner = "drucker_prager and mohr_coulomb";
  } else if (key == "dilatancy_angle_deg" || key == "grain_diameter" ||
             key == "friction_angle_max_deg" || key == "inertial_number_i0") {
    owner = "mohr_coulomb";
  } else if (key == "bulk_modulus" || key == "viscosity" || key == "gamma") {
    owner = "water";
  }
  return owner.empty() ? owner : "a parameter of " + owner + " only";
}

MaterialDesc parseMaterial(const std::string& name, const ParamDict& d) {
  MaterialDesc m;
  m.name = name;
  m.model = d.requireEnum("model", kModels);
  m.density = d.requireDouble("density", Range::positive());
  if (m.model == MaterialModel::Water) {
    m.bulk_modulus = d.requireDouble("bulk_modulus", Range::positive());
    m.viscosity = d.getDouble("viscosity", m.viscosity, Range::nonNegative());
    m.gamma = d.getDouble("gamma", m.gamma, Range::atLeast(1));
  } else {
    // Every solid model is elastic underneath; the plastic ones add a yield rule.
    m.youngs_modulus = d.requireDouble("youngs_modulus", Range::positive());
    m.poisson_ratio = d.requireDouble("poisson_ratio", Range::closedOpen(0, 0.5));
  }
  if (m.model == MaterialModel::Snow) {
    m.critical_compression =
        d.getDouble("critical_compression", m.critical_compression, Range::open(0, 1));
    m.critical_stretch = d.getDouble("critical_stretch", m.critical_stretch, Range::positive());
    m.hardening = d.getDouble("hardening", m.hardening, Range::nonNegative());
  }
  if (m.model == MaterialModel::DruckerPrager || m.model == MaterialModel::MohrCoulomb) {
    m.friction_angle_deg =
        d.getDouble("friction_angle_deg", m.friction_angle_deg, Range::closedOpen(0, 90));
    m.cohesion = d.getDouble("cohesion", m.cohesion, Range::nonNegative());
  }
  if (m.model == MaterialModel::MohrCoulomb) {
    // Granular media dilate at angles below their friction angle.
    m.dilatancy_angle_deg = d.getDouble("dilatancy_angle_deg", m.dilatancy_angle_deg,
                                        Range::closed(0, m.friction_angle_deg));
    // mu(I): the grain size turns it on; the defaults are Jop et al.'s
    // glass beads (20.9 to 32.8 degrees, I_0 = 0.279) shifted to this angle.
    m.grain_diameter = d.getDouble("grain_diameter", 0.0, Range::nonNegative());
    m.friction_angle_max_deg =
        d.getDouble("friction_angle_max_deg",
                    std::min(m.friction_angle_deg + 11.86, 0.5 * (m.friction_angle_deg + 90)),
                    Range::closedOpen(m.friction_angle_deg, 90));
    m.inertial_number_i0 =
        d.getDouble("inertial_number_i0", m.inertial_number_i0, Range::positive());
    for (const char* key : {"friction_angle_max_deg", "inertial_number_i0"})
      if (d.has(key) && m.grain_diameter <= 0)
        d.fail(key, "applies only with mu(I), which a positive \"grain_diameter\" turns on");
  }
  d.checkUnknownKeys("for model " + inQuotes(nameOf(kModels, m.model)), materialKeyHint);
  return m;
}

// Shapes

// `frames`: the scene's frame count, for a mesh sequence's files; -1 where
// sequences are not allowed (reported by the caller).
ShapeDesc parseShape(const ParamDict& s, const std::string& scene_dir, int frames) {
  const bool box = s.has("box"), sphere = s.has("sphere"), mesh = s.has("mesh");
  s.checkUnknownKeys("in a shape");
  if (box + sphere + mesh != 1) {
    std::string got = box + sphere + mesh == 0 ? "none" : "";
    for (const char* k : {"box", "sphere", "mesh"}) {
      if (!s.has(k)) continue;
      got += (got.empty() ? "" : " and ") + inQuotes(k);
    }
    s.fail({}, "expected exactly one of \"box\", \"sphere\" or \"mesh\", got " + got);
  }

  if (box) {
    const ParamDict b = s.requireDict("box");
    BoxDesc out;
    out.min = b.requireVec3("min");
    out.max = b.requireVec3("max");
    requireOrdered(b, out.min, out.max);
    b.checkUnknownKeys("in a box");
    return out;
  }
  if (sphere) {
    const ParamDict b = s.requireDict("sphere");
    SphereDesc out;
    out.center = b.requireVec3("center");
    out.radius = b.requireDouble("radius", Range::positive());
    b.checkUnknownKeys("in a sphere");
    return out;
  }

  const ParamDict m = s.requireDict("mesh");
  MeshDesc out;
  out.path = m.requireString("path");
  out.resolved_path = resolveRelative(scene_dir, out.path);
  out.scale = m.getDouble("scale", out.scale, Range::positive());
  out.translate = m.getVec3("translate", out.translate);
  out.rotate_deg = m.getVec3("rotate_deg", out.rotate_deg);
  m.checkUnknownKeys("in a mesh");
  // A run of '#' in the file name: a mesh sequence, one file per frame.
  const std::string file = fs::path(out.resolved_path).filename().string();
  if (const size_t at = file.find('#'); at != std::string::npos) {
    const size_t end = file.find_first_not_of('#', at);
    out.sequence_digits = int((end == std::string::npos ? file.size() : end) - at);
    if (file.find('#', at + size_t(out.sequence_digits)) != std::string::npos)
      m.fail("path", "expected one run of '#' (the frame number) in a mesh sequence's file "
                     "name, got " + inQuotes(out.path));
    if (frames < 0) return out;  // checked by the caller, which knows the frames
    for (int f = 0; f <= frames; ++f) {
      const std::string p = sequenceFrame(out.resolved_path, out.sequence_digits, f);
      std::error_code ec;
      if (!fs::is_regular_file(p, ec))
        m.fail("path", "expected a file for every frame 0.." + std::to_string(frames) +
                           " of the mesh sequence, but frame " + std::to_string(f) + "'s " +
                           inQuotes(p) + " does not exist (paths are relative to the scene file)");
    }
    return out;
  }
  std::error_code ec;
  const fs::file_status st = fs::status(out.resolved_path, ec);
  if (!fs::exists(st)) {
    m.fail("path", "expected an existing mesh file, but " + inQuotes(out.resolved_path) +
                       " does not exist (paths are relative to the scene file)");
  }
  if (!fs::is_regular_file(st)) {
    m.fail("path", "expected a mesh file, but " + inQuotes(out.resolved_path) + " is not a file");
  }
  return out;
}

// Whether a shape has volume inside the domain. Meshes are not loaded here,
// so their extent is unknown: the mesh importer checks them.
bool overlapsDomain(const ShapeDesc& shape, const DomainDesc& d) {
  if (const auto* b = std::get_if<BoxDesc>(&shape)) {
    for (int a = 0; a < 3; ++a) {
      if (!(b->max[a] > d.min[a] && b->min[a] < d.max[a])) return false;
    }
    return true;
  }
  if (const auto* s = std::get_if<SphereDesc>(&shape)) {
    double dist2 = 0;
    for (int a = 0; a < 3; ++a) {
      const double c = std::clamp(s->center[a], d.min[a], d.max[a]);
      dist2 += (s->center[a] - c) * (s->center[a] - c);
    }
    return dist2 < s->radius * s->radius;
  }
  return true;
}

std::string describeShape(const ShapeDesc& shape) {
  if (const auto* b = std::get_if<BoxDesc>(&shape)) {
    return "a box from " + vecString(b->min) + " to " + vecString(b->max);
  }
  const auto& s = std::get<SphereDesc>(shape);
  return "a sphere at " + vecString(s.center) + " of radius " + formatNumber(s.radius);
}

// Objects

std::string objectKeyHint(ObjectKind kind, const std::string& key) {
  const bool moved = kind == ObjectKind::Collider || kind == ObjectKind::Sink;
  if (moved && (key == "density" || key == "velocity" || key == "angular_velocity" ||
                key == "fixed" || key == "material"))
    return "a " + nameOf(kKinds, kind) +
           " has no mass and is moved only by its \"animation\" (it moves exactly as prescribed)";
  if (key == "animation")
    return "only colliders, sinks and MPM sources (objects with \"emit\") take an animation";
  if (key == "emit") return "only MPM objects can be sources";
  if (key == "material") return "a rigid object takes a density, not a material";
  if (key == "density")
    return "only rigid objects take a density; others get it from their material";
  if (key == "fixed" || key == "angular_velocity") return "only rigid objects take it";
  if (key == "initial_pressure") return "only MPM objects of a water material take it";
  if (key == "integrator" || key == "damping") return "only elastic objects take it";
  if (key == "sample_spacing" && kind == ObjectKind::Mpm)
    return "only rigid, elastic and collider objects take it; MPM objects use "
           "solver.particles_per_cell";
  if ((key == "sample_spacing" || key == "friction") && kind == ObjectKind::Sink)
    return "a sink only removes material: it has no contact";
  if (key == "friction" && kind == ObjectKind::Mpm) {
    return "only rigid and elastic objects take it, for contact with MPM material";
  }
  return {};
}

int resolveMaterial(const ParamDict& d, const std::vector<MaterialDesc>& materials) {
  const std::string name = d.requireString("material");
  std::vector<std::string> names;
  for (std::size_t i = 0; i < materials.size(); ++i) {
    if (materials[i].name == name) return static_cast<int>(i);
    names.push_back(materials[i].name);
  }
  std::string what = "expected the name of an entry of \"materials\", got " + inQuotes(name);
  if (names.empty()) {
    what += ", but the scene defines no materials";
  } else {
    std::string known;
    for (const auto& n : names) known += (known.empty() ? "" : ", ") + inQuotes(n);
    what += "; known materials: " + known;
    if (auto near = closestMatch(name, names)) what += "; did you mean " + inQuotes(*near) + "?";
  }
  d.fail("material", what);
}

// A solid's collision particle spacing (0 when left out: dx/2). At most
// dx: then every grid node next to the solid still lies within the B-spline
// support (1.5 dx) of a sample, so MPM material cannot pass between
// samples. At least dx/8: 64 times the samples of the default per volume,
// and an explicit solid's element step 4 times shorter, for detail the
// grid of the coupling (dx) no longer resolves.
double parseSampleSpacing(const ParamDict& d, const DomainDesc& domain) {
  if (!d.has("sample_spacing")) return 0.0;
  const double s = d.requireDouble("sample_spacing", Range::positive());
  const double lo = domain.dx / 8, hi = domain.dx;
  // Relative slack: dx/8 and dx written as decimals must pass.
  if (s < lo * (1 - 1e-9) || s > hi * (1 + 1e-9))
    d.fail("sample_spacing", "expected a spacing in [dx/8, dx] = [" + formatNumber(lo) + ", " +
                                 formatNumber(hi) + "] m (domain.dx = " + formatNumber(domain.dx) +
                                 "), got " + formatNumber(s));
  return s;
}

// Keys in increasing time, at least one; each a time and optional
// translate and rotate_deg.
AnimationDesc parseAnimation(const ParamDict& a) {
  AnimationDesc out;
  out.interpolation = a.getEnum("interpolation", out.interpolation, kInterpolations);
  const std::vector<ParamDict> keys = a.requireDictArray("keys");
  for (std::size_t k = 0; k < keys.size(); ++k) {
    AnimationKeyDesc key;
    key.time = keys[k].requireDouble("time");
    key.translate = keys[k].getVec3("translate", key.translate);
    key.rotate_deg = keys[k].getVec3("rotate_deg", key.rotate_deg);
    keys[k].checkUnknownKeys("in an animation key");
    if (k > 0 && !(key.time > out.keys.back().time))
      keys[k].fail("time", "expected keys in increasing time: a time after keys[" +
                               std::to_string(k - 1) + "].time = " +
                               formatNumber(out.keys.back().time) + ", got " +
                               formatNumber(key.time));
    out.keys.push_back(key);
  }
  a.checkUnknownKeys("in an animation");
  return out;
}

EmitDesc parseEmit(const ParamDict& e) {
  EmitDesc out;
  out.start = e.getDouble("start", out.start, Range::nonNegative());
  out.end = e.requireDouble("end", Range::positive());
  if (!(out.end > out.start))
    e.fail("end", "expected an end after start = " + formatNumber(out.start) + " s, got " +
                      formatNumber(out.end));
  e.checkUnknownKeys("in emit");
  return out;
}

ObjectDesc parseObject(const ParamDict& d, const std::vector<MaterialDesc>& materials,
                       const DomainDesc& domain, const std::string& scene_dir, int frames) {
  ObjectDesc o;
  o.name = requireSafeName(d, "name");
  o.kind = d.requireEnum("kind", kKinds);
  const ParamDict shape = d.requireDict("shape");
  o.shape = parseShape(shape, scene_dir, o.kind == ObjectKind::Collider ? frames : -1);
  if (const auto* m = std::get_if<MeshDesc>(&o.shape); m && m->sequence_digits > 0 &&
                                                        o.kind != ObjectKind::Collider)
    shape.requireDict("mesh").fail(
        "path", "expected one mesh file: mesh sequences (a run of '#' in the path, "
                "the frame number) are for colliders only, and this object is of kind " +
                    inQuotes(nameOf(kKinds, o.kind)));
  const bool moved = o.kind == ObjectKind::Collider || o.kind == ObjectKind::Sink;
  if (!moved) o.velocity = d.getVec3("velocity", o.velocity);

  // Read the keys that this kind takes
  switch (o.kind) {
    case ObjectKind::Mpm:
      o.material = resolveMaterial(d, materials);
      if (auto e = d.getDict("emit")) o.emit = parseEmit(*e);
      o.initial_pressure = d.getEnum("initial_pressure", o.initial_pressure, kInitialPressures);
      if (o.initial_pressure == InitialPressure::Hydrostatic) {
        const MaterialDesc& m = materials[static_cast<std::size_t>(o.material)];
        if (m.model != MaterialModel::Water)
          d.fail("initial_pressure",
                 "expected a water material for \"hydrostatic\" (the "
                 "pressure of water at rest), got " +
                     inQuotes(m.name) + " of model " + inQuotes(nameOf(kModels, m.model)));
        if (o.emit)
          d.fail("initial_pressure",
                 "expected \"none\" for a source: its water is made "
                 "moving, not at rest");
      }
      // A source may move; a body of material moves by its own physics.
      if (o.emit)
        if (auto a = d.getDict("animation")) o.animation = parseAnimation(*a);
      break;
    case ObjectKind::Collider:
      if (auto a = d.getDict("animation")) o.animation = parseAnimation(*a);
      o.friction = d.getDouble("friction", o.friction, Range::nonNegative());
      o.sample_spacing = parseSampleSpacing(d, domain);
      o.fixed = true;  // never moved by anything
      break;
    case ObjectKind::Sink:
      if (auto a = d.getDict("animation")) o.animation = parseAnimation(*a);
      break;
    case ObjectKind::Elastic: {
      o.material = resolveMaterial(d, materials);
      const MaterialDesc& m = materials[static_cast<std::size_t>(o.material)];
      // The elastic solver has no plasticity or fluid pressure.
      if (m.model != MaterialModel::FixedCorotated && m.model != MaterialModel::NeoHookean) {
        d.fail("material", "expected a fixed_corotated or neo_hookean material, got " +
                               inQuotes(m.name) + " of model " +
                               inQuotes(nameOf(kModels, m.model)));
      }
      o.friction = d.getDouble("friction", o.friction, Range::nonNegative());
      o.integrator = d.getEnum("integrator", o.integrator, kIntegrators);
      o.damping = d.getDouble("damping", o.damping, Range::nonNegative());
      if (o.damping > 0.0 && o.integrator == ElasticIntegrator::Implicit)
        d.fail("damping", "expected 0 with \"integrator\": \"implicit\" (backward Euler "
                          "damps by itself; damping is for the explicit integrator)");
      o.sample_spacing = parseSampleSpacing(d, domain);
      break;
    }
    case ObjectKind::Rigid:
      o.density = d.requireDouble("density", Range::positive());
      o.fixed = d.getBool("fixed", o.fixed);
      o.angular_velocity = d.getVec3("angular_velocity", o.angular_velocity);
      o.friction = d.getDouble("friction", o.friction, Range::nonNegative());
      o.sample_spacing = parseSampleSpacing(d, domain);
      break;
  }
  d.checkUnknownKeys("for an object of kind " + inQuotes(nameOf(kKinds, o.kind)),
                     [&](const std::string& key) { return objectKeyHint(o.kind, key); });

  // A fixed body never moves, so an initial motion contradicts it.
  const Vec3Desc zero{0, 0, 0};
  if (o.kind == ObjectKind::Rigid && o.fixed && o.velocity != zero) {
    d.fail("velocity", "expected no motion for a fixed object, got " + vecString(o.velocity));
  }
  if (o.kind == ObjectKind::Rigid && o.fixed && o.angular_velocity != zero) {
    d.fail("angular_velocity",
           "expected no motion for a fixed object, got " + vecString(o.angular_velocity));
  }
  if (!overlapsDomain(o.shape, domain)) {
    d.fail("shape", "expected a shape at least partly inside the domain (" + vecString(domain.min) +
                        " to " + vecString(domain.max) + "), got " + describeShape(o.shape));
  }
  return o;
}

// Output and preview render

OutputDesc parseOutput(const ParamDict& root, const std::string& name,
                       const std::string& scene_dir) {
  OutputDesc out;
  // The default follows the contract's "out/<name>", taken relative to the
  // working directory (where the user runs triad), not to the scene file.
  out.dir = (fs::path("out") / name).string();
  if (auto o = root.getDict("output")) {
    if (o->has("dir")) out.dir = resolveRelative(scene_dir, o->requireString("dir"));
    out.ply = o->getBool("ply", out.ply);
    out.vdb = o->getBool("vdb", out.vdb);
    out.png = o->getBool("png", out.png);
    // Left out (0): the domain's dx, resolved where the volumes are written.
    if (o->has("vdb_voxel_size"))
      out.vdb_voxel_size = o->requireDouble("vdb_voxel_size", Range::positive());
    out.vdb_surface = o->getBool("vdb_surface", out.vdb_surface);
    out.surface_mesh = o->getBool("surface_mesh", out.surface_mesh);
    out.surface_smoothing =
        o->getInt("surface_smoothing", out.surface_smoothing, Range::closed(0, 20));
    out.surface_adaptivity =
        o->getDouble("surface_adaptivity", out.surface_adaptivity, Range::closed(0, 1));
    out.vtk = o->getBool("vtk", out.vtk);
    out.checkpoints = o->getBool("checkpoints", out.checkpoints);
    o->checkUnknownKeys();
  }
  return out;
}

RenderDesc parseRender(const ParamDict& root) {
  RenderDesc out;
  auto r = root.getDict("render");
  if (!r) return out;
  out.resolution = r->getIntPair("resolution", out.resolution, Range::closed(16, 8192));
  out.style = r->getEnum<RenderStyle>(
      "style", out.style, {{"particles", RenderStyle::Particles}, {"surface", RenderStyle::Surface}});
  out.legend = r->getBool("legend", out.legend);
  if (auto c = r->getDict("camera")) {
    CameraDesc cam;
    cam.eye = c->requireVec3("eye");
    cam.target = c->requireVec3("target");
    if (cam.eye == cam.target) {
      c->fail("target",
              "expected a point other than eye (the view direction would be undefined), got " +
                  vecString(cam.target) + " for both");
    }
    cam.fov_deg = c->getDouble("fov_deg", cam.fov_deg, Range::open(0, 180));
    c->checkUnknownKeys();
    out.camera = cam;
  }
  r->checkUnknownKeys();
  return out;
}

}  // namespace

nlohmann::ordered_json solverSettings(const SolverDesc& s) {
  // In parseSolver's order, and only the keys it accepts with this
  // coupling and transfer.
  nlohmann::ordered_json j;
  j["cfl"] = s.cfl;
  j["max_dt"] = s.max_dt;
  j["particles_per_cell"] = s.particles_per_cell;
  j["transfer"] = nameOf(kTransfers, s.transfer);
  if (s.transfer == TransferScheme::Flip) j["flip_ratio"] = s.flip_ratio;
  j["coupling"] = nameOf(kCouplings, s.coupling);
  if (s.coupling == CouplingScheme::ThreeGrid) {
    j["contact_reach"] = s.contact_reach;
    j["contact_normal"] = nameOf(kContactNormals, s.contact_normal);
    j["rigid_collision"] = nameOf(kRigidCollisions, s.rigid_collision);
    j["contact_gap"] = s.contact_gap;
    j["contact_gap_fixed"] = s.contact_gap_fixed;
    j["front_fields"] = s.front_fields;
    j["elastic_contact_passes"] = s.elastic_contact_passes;
    j["front_angle_deg"] = s.front_angle_deg;
  }
  j["contact_velocity"] = nameOf(kContactVelocities, s.contact_velocity);
  j["solid_readback"] = nameOf(kReadbacks, s.solid_readback);
  j["rigid_node_mass"] = nameOf(kNodeMasses, s.rigid_node_mass);
  j["rigid_node_velocity"] = nameOf(kNodeVelocities, s.rigid_node_velocity);
  j["coupling_iterations"] = s.coupling_iterations;
  j["contact_iterations"] = s.contact_iterations;
  if (s.sleep.enabled)
    j["sleep"] = {
        {"speed", s.sleep.speed}, {"delay", s.sleep.delay}, {"neighbours", s.sleep.neighbours}};
  else
    j["sleep"] = false;
  return j;
}

SceneDesc parseScene(const nlohmann::json& j, const std::string& source_path) {
  const ParamDict root(j, source_path);
  const std::string scene_dir = fs::path(source_path).parent_path().string();
  SceneDesc scene;
  scene.source_path = source_path;

  // Read the top-level sections
  scene.version = root.requireInt("version");
  if (scene.version != 1) {
    root.fail("version", "expected 1 (the only scene format version this build reads), got " +
                             std::to_string(scene.version));
  }
  scene.name = requireSafeName(root, "name");
  scene.frames = parseFrames(root);
  scene.domain = parseDomain(root);
  scene.gravity = root.getVec3("gravity", scene.gravity);
  scene.solver = parseSolver(root);
  for (const auto& [name, dict] : root.getNamedDicts("materials")) {
    scene.materials.push_back(parseMaterial(name, dict));
  }

  // Read the objects, whose names must be unique: they name output files,
  // also on file systems that ignore case.
  std::map<std::string, std::size_t> seen;
  const std::vector<ParamDict> objects = root.requireDictArray("objects");
  if (objects.size() > kMaxObjects) {
    root.fail("objects", "expected at most " + std::to_string(kMaxObjects) + " objects, got " +
                             std::to_string(objects.size()));
  }
  for (std::size_t i = 0; i < objects.size(); ++i) {
    ObjectDesc o =
        parseObject(objects[i], scene.materials, scene.domain, scene_dir, scene.frames.count);
    std::string folded = o.name;
    for (char& ch : folded) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    auto [it, inserted] = seen.emplace(folded, i);
    if (!inserted) {
      objects[i].fail("name", "expected a name unique among objects (ignoring case), got " +
                                  inQuotes(o.name) + ", already the name of objects[" +
                                  std::to_string(it->second) + "]");
    }
    scene.objects.push_back(std::move(o));
  }

  scene.output = parseOutput(root, scene.name, scene_dir);
  // Surface meshes are named after their material.
  if (scene.output.surface_mesh) {
    std::map<std::string, std::string> folded_names;
    for (const auto& [name, dict] : root.getNamedDicts("materials")) {
      if (!isSafeName(name))
        dict.fail("", "with output.surface_mesh, a material's name names its files "
                      "(surfaces/NAME.FFFF.ply): expected the characters A-Z a-z 0-9 _ . -, got " +
                          inQuotes(name));
      std::string folded = name;
      for (char& ch : folded) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
      auto [it, inserted] = folded_names.emplace(folded, name);
      if (!inserted)
        dict.fail("", "with output.surface_mesh, material names must differ other than in case "
                      "(they name files), got " + inQuotes(name) + " and " + inQuotes(it->second));
    }
  }
  scene.render = parseRender(root);
  root.checkUnknownKeys();
  return scene;
}

}  // namespace triad
