#pragma once
// The files of one frame (particles, volumes, rigid bodies, checkpoint) and
// finding where a killed run can resume. runScene (app/run_scene.cpp) calls
// these in order.
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "export/body_writer.h"
#include "export/checkpoint.h"
#include "export/vdb_writer.h"
#include "sim/scene_desc.h"
#include "sim/solver.h"
#include "sim/world.h"

namespace triad {
namespace render {
struct Image;
}

// Cache paths, shared with readers and tests (particlesPath: run_scene.h).
std::string volumesPath(const std::string& out_dir, int frame);
std::string checkpointDir(const std::string& out_dir);
std::string checkpointPath(const std::string& out_dir, int frame);
std::string bodiesDir(const std::string& out_dir);
std::string bodyMeshPath(const std::string& out_dir, const std::string& name, int frame);
std::string rigidStatesPath(const std::string& out_dir);
std::string bodyForcesPath(const std::string& out_dir);
std::string surfacesDir(const std::string& out_dir);
std::string vtkDir(const std::string& out_dir);
std::string vtkParticlesPath(const std::string& out_dir, int frame);
std::string surfaceMeshPath(const std::string& out_dir, const std::string& material, int frame);

// The materials whose surfaces output.surface_mesh writes: those of the
// scene's MPM objects, as indices into scene.materials, ascending.
std::vector<int> surfaceMaterials(const SceneDesc& scene);

// The run-long tables of bodies/: their rows of the frames written so far.
struct BodyLogs {
  RigidStateLog states;  // rigid_states.csv, frames 0..
  BodyForceLog forces;   // forces.csv, frames 1..
};

// Creates the folders the scene's outputs need under out_dir (bodies/ when
// the scene has rigid objects).
void makeOutputDirectories(const SceneDesc& scene, const std::string& out_dir);

// A split run's frame files that its processes wrote together: the
// temporaries to rename into place (empty: not written that way), the
// volumes' sums they splatted (null: splat the world's particles) and the
// preview they drew.
struct SharedWrites {
  std::string particles, vtk_particles, checkpoint;
  struct Volumes {
    std::vector<VoxelSum> sums;
    VolumeScale scale;
  };
  std::shared_ptr<const Volumes> volumes;
  // The preview its processes drew together (null: draw the world's particles).
  std::shared_ptr<const render::Image> preview;
  // The level sets they made in parts, by material (-1: the volumes'
  // `surface`; null: make them from the world's particles).
  std::shared_ptr<const std::map<int, LevelSetParts>> surfaces;
};

// Writes the frame's cache files that the scene asks for: PLY particles, the
// VDB volumes (voxel size output.vdb_voxel_size, else domain.dx) and each
// material's surface mesh (its level set's voxel bounded by the same size),
// and with output.vtk the same as VTK PolyData, the solids' surfaces with
// them, and vtk/cache.pvd listing frames 0..frame.
// Returns the material surfaces it made (material index, mesh): with
// output.surface_mesh, or previews (output.png) in render.style "surface";
// else none.
// `shared`: what the processes of a split run wrote or splatted already.
std::vector<std::pair<int, TriSurface>> writeFrameCaches(const SceneDesc& scene,
                                                         const std::string& out_dir,
                                                         const World& world, int frame,
                                                         const SharedWrites& shared = {});

// Writes the frame's rigid body caches: every body's surface, then the state
// table with this frame's rows recorded in `logs`, and for frames after the
// first the force table from `loads` (the solver's, since the frame before).
// Body caches are small and are written whatever output.ply/vdb/png say,
// like run.json. Nothing is written for a world without bodies.
void writeFrameBodies(const std::string& out_dir, const World& world, int frame, BodyLogs& logs,
                      const std::vector<BodyLoad>& loads);

// Writes the frame's checkpoint (or renames `written`, its temporary,
// into place), then deletes all but it and the one before.
void writeFrameCheckpoint(const std::string& out_dir, int frame, const std::string& scene_hash,
                          const World& world, const SolverState& solver, const StepRecord& record,
                          const std::string& written = "");

// Deletes temporaries (NAME.tmpPID) that a killed run left in the cache
// folders. Call before this run writes anything.
void removeStaleTemporaries(const std::string& out_dir);

// Deletes every checkpoint in out_dir (a fresh run must not leave stale ones
// from an earlier run for a later --resume).
void removeCheckpoints(const std::string& out_dir);

// Removes the frame files (particles, volumes, body and surface meshes, previews)
// numbered above `last_frame`, left by an earlier, longer run into the same
// directory: they would otherwise be mistaken for this run's frames (the
// contact sheet, a renderer reading the sequence).
void removeFramesAfter(const std::string& out_dir, int last_frame);

// Removes the body caches of an earlier run that are not this world's:
// meshes of bodies it does not have, and the state table when it has none;
// and the surface meshes of materials this scene does not mesh.
void removeOtherBodies(const std::string& out_dir, const World& world);

// Where a resumed run continues: the state after `frame` has been restored.
struct ResumePoint {
  int frame = 0;
  std::string checkpoint;  // its path
  StepRecord record;       // step statistics of the run up to that frame
  BodyLogs logs;           // body table rows up to frame (bodies only)
};

// What a checkpoint records as its scene: the scene file's hash, and the
// --quality preset when there is one ("fnv1a64:<hex>+quality:draft"), so
// that a run never resumes from a checkpoint of another resolution.
std::string checkpointKey(const std::string& scene_hash, const std::string& quality);

// Restores `world` and `solver` from the newest checkpoint in out_dir that
// reads back intact, belongs to this scene file, fits the world built from
// it, and whose frame's cache files are complete (body meshes, and the state
// table's rows of every frame up to it, included); nullopt (nothing changed)
// if there is none. Checkpoints passed over are reported on stderr. Throws
// InputError (exit status 2) when that checkpoint was written for a
// different scene file or under a different --quality (`key` is
// checkpointKey's). With `share` (a split run), only this process's share
// of the checkpoint's particles is read.
std::optional<ResumePoint> resumeFromCheckpoint(const SceneDesc& scene, const std::string& out_dir,
                                                const std::string& key, World& world,
                                                Solver& solver, ParticleShare* share = nullptr);

}  // namespace triad
