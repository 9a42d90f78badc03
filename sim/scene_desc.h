#pragma once
// Plain description of a scene: what the JSON file says, validated and with
// defaults filled in, but no runtime objects. The scene loader (import/)
// produces it; World::build (sim/world.h) turns it into solver state in one
// place. Units are SI throughout; angles are stored in degrees as written.
#include <array>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace triad {

using Vec3Desc = std::array<double, 3>;

enum class BoundaryType { Slip, Sticky, Separate };
enum class TransferScheme { Apic, Pic, Flip };
enum class CouplingScheme { ThreeGrid, SingleGrid };
// Open choices of coupling.md: which MPM velocity the collision compares
// with the solid's, and what the solids read back from the grid.
enum class ContactVelocity { AfterUpdate, BeforeUpdate };
enum class SolidReadback { MomentumConserving, Combined };
// The solid mass in a collision's reduced mass at a rigid body's node: the
// body's mass shared over its nodes in contact, or the node's own (literal).
enum class RigidNodeMass { BodyShare, Node };
// Three grids: the solid velocity a collision compares at a moving rigid
// body's node, the body's own there or its samples' mean (the contract's).
enum class RigidNodeVelocity { Body, Samples };
// Three grids: a node's contact normal, from the samples' summed normals
// (the contract's step 4) or from the body's own signed distance.
enum class ContactNormal { Samples, Distance };
// Three grids: how a moving rigid body's nodes are solved together, by
// Jacobi passes over the nodes or by Newton's method on the body's velocity.
enum class RigidCollision { Jacobi, Newton };

enum class MaterialModel { FixedCorotated, NeoHookean, Snow, DruckerPrager, MohrCoulomb, Water };
enum class ObjectKind { Mpm, Rigid, Elastic, Collider, Sink };
enum class ElasticIntegrator { Explicit, Implicit };

struct FramesDesc {
  int count = 48;
  double fps = 24.0;
};

struct BoundaryDesc {
  BoundaryType type = BoundaryType::Slip;
  double friction = 0.0;  // Coulomb coefficient against the domain walls
};

struct DomainDesc {
  Vec3Desc min{0, 0, 0};
  Vec3Desc max{1, 1, 1};
  double dx = 0.02;
  BoundaryDesc boundary;
};

// Settled material sleeps (sim/mpm/sleep.h): a particle block whose
// particles have all been slower than `speed` for `delay` seconds skips its
// work until motion or a moving solid comes near.
struct SleepDesc {
  bool enabled = false;
  double speed = 0.01;  // m/s
  double delay = 0.2;   // s
  // A block sleeps only once the blocks around it have been still for the
  // delay too. Off, material creeping beside a sleeping block is held back
  // by it (faster, less exact: bench/RESULTS.md, "Sleeping material").
  bool neighbours = true;
};

struct SolverDesc {
  double cfl = 0.4;      // fraction of a cell travelled (by material or waves) per step
  double max_dt = 1e-3;  // upper bound on the step, seconds
  int particles_per_cell = 8;
  TransferScheme transfer = TransferScheme::Apic;
  double flip_ratio = 0.95;  // FLIP share of the PIC/FLIP blend (transfer "flip")
  CouplingScheme coupling = CouplingScheme::ThreeGrid;
  ContactVelocity contact_velocity = ContactVelocity::AfterUpdate;
  SolidReadback solid_readback = SolidReadback::MomentumConserving;
  RigidNodeMass rigid_node_mass = RigidNodeMass::Node;
  RigidNodeVelocity rigid_node_velocity = RigidNodeVelocity::Body;
  // Three grids: how far outside a rigid body's surface, in cells, a node
  // still takes part in the contact (its signed distance, extrapolated from
  // the samples). 1.5 takes every node the samples' stencils reach.
  double contact_reach = 1.5;
  bool front_fields = false;      // two fields on moving solids' nodes (front_fields.cpp)
  double front_angle_deg = 45.0;  // a node's face within it of a particle's nearest: in front
  ContactNormal contact_normal = ContactNormal::Distance;
  RigidCollision rigid_collision = RigidCollision::Newton;
  // Three grids: material a gap away from a rigid solid may close it in a
  // step before the collision stops it (a speculative contact).
  bool contact_gap = true;
  // Fixed solids take the gap too: material falling onto them rests half a
  // spacing off their faces, not up to a cell above them.
  bool contact_gap_fixed = true;
  int coupling_iterations = 30;  // most Jacobi passes of the grid collision with rigid bodies
  // Three grids: passes that make the collision hold for what elastic
  // solids' points read back (0: the contract's one pass).
  int elastic_contact_passes = 8;
  int contact_iterations = 20;  // sequential-impulse passes for rigid contacts
  SleepDesc sleep;
};

// Every model's parameters in one flat struct; the loader fills the fields
// that the named model takes and rejects the others.
struct MaterialDesc {
  std::string name;
  MaterialModel model = MaterialModel::FixedCorotated;
  double density = 1000.0;
  // Elastic moduli (all solid models).
  double youngs_modulus = 0.0;
  double poisson_ratio = 0.0;
  // Snow (Stomakhin et al. 2013).
  double critical_compression = 2.5e-2;
  double critical_stretch = 7.5e-3;
  double hardening = 10.0;
  // Drucker-Prager and Mohr-Coulomb sand. Cohesion in pascals; the
  // dilatancy angle (Mohr-Coulomb only) sets the plastic flow's volume change.
  double friction_angle_deg = 30.0;
  double cohesion = 0.0;
  double dilatancy_angle_deg = 0.0;
  // Mohr-Coulomb's mu(I): on when grain_diameter (m) > 0; the friction
  // angle rises from friction_angle_deg at rest to friction_angle_max_deg.
  double grain_diameter = 0.0;
  double friction_angle_max_deg = 0.0;
  double inertial_number_i0 = 0.279;
  // Weakly compressible water (Tait equation of state).
  double bulk_modulus = 0.0;
  double viscosity = 0.0;  // dynamic viscosity, Pa s
  double gamma = 7.0;      // Tait exponent
};

struct BoxDesc {
  Vec3Desc min{0, 0, 0};
  Vec3Desc max{0, 0, 0};
};

struct SphereDesc {
  Vec3Desc center{0, 0, 0};
  double radius = 0.0;
};

struct MeshDesc {
  std::string path;           // as written in the scene (relative to it)
  std::string resolved_path;  // absolute or relative to the working directory
  // A mesh sequence: the width of the run of '#' in the path, which stands
  // for the frame number zero-padded to it (0: one file).
  int sequence_digits = 0;
  double scale = 1.0;
  Vec3Desc translate{0, 0, 0};
  Vec3Desc rotate_deg{0, 0, 0};  // XYZ Euler, applied after scale, before translate
};

using ShapeDesc = std::variant<BoxDesc, SphereDesc, MeshDesc>;

// The file of a mesh sequence's frame: the run of '#' in `path` replaced by
// the frame number, zero-padded to its width.
inline std::string sequenceFrame(const std::string& path, int digits, int frame) {
  const size_t at = path.find(std::string(size_t(digits), '#'));
  std::string number = std::to_string(frame);
  if (number.size() < size_t(digits)) number.insert(0, size_t(digits) - number.size(), '0');
  return path.substr(0, at) + number + path.substr(at + size_t(digits));
}

// A prescribed motion (colliders, sources, sinks): poses at key times, each
// a translation and an XYZ Euler rotation about the centroid of the shape's
// volume as written. Keys are in increasing time.
enum class Interpolation { Linear, Smooth };

struct AnimationKeyDesc {
  double time = 0.0;
  Vec3Desc translate{0, 0, 0};
  Vec3Desc rotate_deg{0, 0, 0};
};

struct AnimationDesc {
  Interpolation interpolation = Interpolation::Linear;
  std::vector<AnimationKeyDesc> keys;  // at least one
};

// An MPM object that is a source from `start` to `end` (seconds).
struct EmitDesc {
  double start = 0.0;
  double end = 0.0;
};

// The state an MPM object's water starts in: no pressure (J = 1), or the
// pressure of the water above it at rest.
enum class InitialPressure { None, Hydrostatic };

struct ObjectDesc {
  std::string name;
  ObjectKind kind = ObjectKind::Mpm;
  int material = -1;  // index into SceneDesc::materials (mpm, elastic)
  ShapeDesc shape;
  Vec3Desc velocity{0, 0, 0};
  Vec3Desc angular_velocity{0, 0, 0};  // rad/s (rigid)
  double density = 0.0;                // rigid only
  bool fixed = false;                  // rigid only
  double friction = 0.0;               // against MPM material (rigid, elastic)
  ElasticIntegrator integrator = ElasticIntegrator::Explicit;  // elastic only
  double damping = 0.0;  // Pa s, Kelvin-Voigt viscosity (explicit elastic only)
  double sample_spacing = 0.0;  // m, collision particle spacing (rigid, elastic, collider); 0: dx / 2
  std::optional<AnimationDesc> animation;  // collider, sink, mpm source
  std::optional<EmitDesc> emit;            // mpm only: a source
  InitialPressure initial_pressure = InitialPressure::None;  // mpm water only
};

struct OutputDesc {
  std::string dir;  // resolved: defaults to out/<name>
  bool ply = true;
  bool vdb = true;
  bool png = true;
  double vdb_voxel_size = 0.0;  // m; 0: the domain's dx
  bool vdb_surface = false;     // also a narrow-band level set `surface`
  bool surface_mesh = false;    // surfaces/MATERIAL.FFFF.ply per material
  int surface_smoothing = 1;    // Gaussian passes on the level set before meshing
  double surface_adaptivity = 0.0;  // OpenVDB volume-to-mesh adaptivity, [0, 1]
  bool vtk = false;             // vtk/: VTK XML PolyData per frame and vtk/cache.pvd
  bool checkpoints = true;      // checkpoints/state.FFFF.bin, for --resume
};

struct CameraDesc {
  Vec3Desc eye{0, 0, 0};
  Vec3Desc target{0, 0, 0};
  double fov_deg = 40.0;
};

// What the preview draws MPM material as: sprites per particle, or the
// material's surface mesh (export/particle_surface.h) in its model's colour.
enum class RenderStyle { Particles, Surface };

struct RenderDesc {
  std::array<int, 2> resolution{640, 360};
  RenderStyle style = RenderStyle::Particles;
  bool legend = true;  // names and colours of what is drawn, top left
  int supersample = 3;  // rendered at this many times the resolution, then box-filtered
  std::optional<CameraDesc> camera;  // absent: frame the domain automatically
};

struct SceneDesc {
  std::string source_path;  // the scene file, for messages
  int version = 1;
  std::string name;
  FramesDesc frames;
  DomainDesc domain;
  Vec3Desc gravity{0, -9.81, 0};
  SolverDesc solver;
  std::vector<MaterialDesc> materials;
  std::vector<ObjectDesc> objects;
  OutputDesc output;
  RenderDesc render;
};

}  // namespace triad
