// Cache writers read back independently: the VDB volumes through OpenVDB
// itself (and vdb_print), the PLY particles through a small reader written
// here that shares nothing with export/ply_writer.cpp.
#include <gtest/gtest.h>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include "export/checkpoint.h"
#include "export/ply_writer.h"
#include "export/vdb_writer.h"
#include "scene_fixture.h"
#include "sim/solver.h"

namespace triad {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Two materials (two particle sets), moving with a velocity that varies in
// space, so that mass and momentum sums test every particle.
World movingWorld(const fs::path& dir) {
  json j = test::baseScene("vdb_scene", {0.4, 0.4, 0.4}, 0.02);
  j["materials"] = {
      {"jelly", {{"model", "fixed_corotated"}, {"density", 1000}, {"youngs_modulus", 5e4},
                 {"poisson_ratio", 0.3}}},
      {"water", {{"model", "water"}, {"density", 997}, {"bulk_modulus", 1e5}}}};
  j["objects"] = {
      {{"name", "cube"}, {"kind", "mpm"}, {"material", "jelly"},
       {"shape", test::box({0.05, 0.05, 0.05}, {0.15, 0.17, 0.13})}, {"velocity", {1, 0, 0}}},
      {{"name", "ball"}, {"kind", "mpm"}, {"material", "water"},
       {"shape", {{"sphere", {{"center", {0.27, 0.25, 0.26}}, {"radius", 0.06}}}}}}};
  World w = test::loadWorld(dir, j);
  for (ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i)
      s.v[i] = Vec3f(1.0f + s.x[i].y(), -2.0f * s.x[i].x(), 0.5f) + s.v[i];
  w.time = 0.125;
  return w;
}

// The frame description the tests write movingWorld with.
VdbFrameInfo vdbInfo(double voxel_size, bool surface = false) {
  VdbFrameInfo info;
  info.scene_name = "vdb_scene";
  info.voxel_size = voxel_size;
  info.surface = surface;
  return info;
}

struct ParticleBounds {
  Vec3d lo = Vec3d::Constant(1e30), hi = Vec3d::Constant(-1e30);
};

ParticleBounds bounds(const World& w) {
  ParticleBounds b;
  for (const ParticleSet& s : w.sets)
    for (const Vec3f& x : s.x) {
      b.lo = b.lo.cwiseMin(x.cast<double>());
      b.hi = b.hi.cwiseMax(x.cast<double>());
    }
  return b;
}

template <class T>
T meta(const openvdb::MetaMap& m, const std::string& name) {
  return m.metaValue<T>(name);
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class VdbExport : public ::testing::Test {
 protected:
  void SetUp() override { openvdb::initialize(); }
};

TEST_F(VdbExport, GridsMetadataMassAndVelocityReadBack) {
  const fs::path dir = test::tempDir("vdb_export");
  const World w = movingWorld(dir);
  ASSERT_EQ(w.sets.size(), 2u);
  const double h = 0.02;
  VdbFrameInfo info;
  info.frame = 3;
  info.time = w.time;
  info.scene_name = "vdb_scene";
  info.voxel_size = h;
  info.surface = true;
  const std::string path = (dir / "density.0003.vdb").string();
  writeVolumesVdb(path, w, info);
  EXPECT_TRUE(checkVolumesVdb(path).empty()) << checkVolumesVdb(path);

  openvdb::io::File file(path);
  file.open();
  // The file's own metadata.
  openvdb::MetaMap::Ptr file_meta = file.getMetadata();
  EXPECT_EQ(meta<int32_t>(*file_meta, "frame"), 3);
  EXPECT_EQ(meta<double>(*file_meta, "time"), 0.125);
  EXPECT_EQ(meta<std::string>(*file_meta, "scene"), "vdb_scene");
  std::map<std::string, openvdb::GridBase::Ptr> grids;
  const openvdb::GridPtrVecPtr all = file.getGrids();
  for (const auto& g : *all) grids[g->getName()] = g;
  file.close();
  ASSERT_EQ(grids.size(), 3u);
  ASSERT_TRUE(grids.count("density") && grids.count("vel") && grids.count("surface"));

  // Classes, types, voxel sizes and per-grid metadata.
  auto density = openvdb::gridPtrCast<openvdb::FloatGrid>(grids["density"]);
  auto vel = openvdb::gridPtrCast<openvdb::Vec3SGrid>(grids["vel"]);
  auto surface = openvdb::gridPtrCast<openvdb::FloatGrid>(grids["surface"]);
  ASSERT_TRUE(density && vel && surface);
  EXPECT_EQ(density->getGridClass(), openvdb::GRID_FOG_VOLUME);
  EXPECT_EQ(vel->getVectorType(), openvdb::VEC_CONTRAVARIANT_RELATIVE);
  EXPECT_EQ(surface->getGridClass(), openvdb::GRID_LEVEL_SET);
  EXPECT_NEAR(density->voxelSize()[0], h, 1e-12);
  EXPECT_NEAR(vel->voxelSize()[2], h, 1e-12);
  const SurfaceSampling ss = surfaceSampling(w, h);
  EXPECT_NEAR(surface->voxelSize()[1], ss.voxel_size, 1e-12);
  EXPECT_LE(ss.voxel_size, 0.5 * ss.radius + 1e-12);
  for (const auto& [name, units] : std::map<std::string, std::string>{
           {"density", "kg/m^3"}, {"vel", "m/s"}, {"surface", "m"}}) {
    EXPECT_EQ(meta<std::string>(*grids[name], "units"), units) << name;
    EXPECT_EQ(meta<int32_t>(*grids[name], "frame"), 3) << name;
    EXPECT_EQ(meta<double>(*grids[name], "time"), 0.125) << name;
    EXPECT_EQ(meta<std::string>(*grids[name], "scene"), "vdb_scene") << name;
  }

  // Active voxel centres cover the particles, at most one voxel beyond.
  const ParticleBounds pb = bounds(w);
  const openvdb::CoordBBox bb = density->evalActiveVoxelBoundingBox();
  for (int d = 0; d < 3; ++d) {
    EXPECT_LE(bb.min()[d] * h, pb.lo[d] + 1e-9) << d;
    EXPECT_GT(bb.min()[d] * h, pb.lo[d] - h) << d;
    EXPECT_GE(bb.max()[d] * h, pb.hi[d] - 1e-9) << d;
    EXPECT_LT(bb.max()[d] * h, pb.hi[d] + h) << d;
  }
  EXPECT_EQ(density->activeVoxelCount(), vel->activeVoxelCount());

  // Total mass and momentum: density x voxel volume and v against the particles.
  const test::Moments pm = test::moments(w);
  double mass = 0.0, max_density = 0.0;
  Vec3d momentum = Vec3d::Zero();
  auto va = vel->getConstAccessor();
  for (auto it = density->cbeginValueOn(); it; ++it) {
    const double m = double(*it) * h * h * h;
    const openvdb::Vec3s v = va.getValue(it.getCoord());
    mass += m;
    momentum += m * Vec3d(v.x(), v.y(), v.z());
    max_density = std::max(max_density, double(*it));
    EXPECT_GT(*it, 0.0f);
  }
  EXPECT_NEAR(mass, pm.mass, 1e-5 * pm.mass);
  const Vec3d mean_v = pm.momentum / pm.mass;
  const Vec3d grid_v = momentum / mass;
  EXPECT_LT((grid_v - mean_v).norm(), 1e-4 * (1.0 + mean_v.norm()))
      << grid_v.transpose() << " vs " << mean_v.transpose();
  // Voxel by voxel, v is the particles' field, (1 + y, -2 x, 0.5) plus the
  // cube's (1, 0, 0): exact where the voxel is full of material (its mass
  // centred on the voxel centre), off by the field's gradient times the
  // offset of the mass from the centre in voxels at the material's edge.
  double worst_full = 0.0, worst_edge = 0.0;
  size_t full = 0;
  const auto& vxf = vel->transform();
  for (auto it = density->cbeginValueOn(); it; ++it) {
    const openvdb::Vec3d c = vxf.indexToWorld(it.getCoord());
    const Vec3d expected = Vec3d(1.0 + c.y(), -2.0 * c.x(), 0.5) + (c.x() < 0.2 ? Vec3d(1, 0, 0) : Vec3d::Zero());
    const openvdb::Vec3s v = va.getValue(it.getCoord());
    const double err = (Vec3d(v.x(), v.y(), v.z()) - expected).norm();
    const bool is_full = double(*it) > 0.99 * (c.x() < 0.2 ? 1000.0 : 997.0);
    (is_full ? worst_full : worst_edge) = std::max(is_full ? worst_full : worst_edge, err);
    full += is_full;
  }
  std::printf("v per voxel: %zu full voxels within %.4f m/s, edge voxels within %.4f m/s\n", full,
              worst_full, worst_edge);
  // Measured: 60 full voxels within 1e-4 m/s, the edge ones within 0.034.
  // Bounds: 1e-3 (a field one voxel off is 0.045 out everywhere), and the
  // gradient (2.24 /s) times one voxel plus 10% at the edge.
  EXPECT_GT(full, 30u);
  EXPECT_LT(worst_full, 1e-3);
  EXPECT_LT(worst_edge, 1.1 * std::sqrt(5.0) * h);

  // Interior voxels hold the material density (kg/m^3), never much more.
  EXPECT_GT(max_density, 0.9 * 997.0);
  EXPECT_LT(max_density, 1.05 * 1000.0);

  // The level set: negative at every particle, background far outside.
  auto sa = surface->getConstAccessor();
  const auto& xf = surface->transform();
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); i += 7) {
      const openvdb::Coord c =
          xf.worldToIndexNodeCentered(openvdb::Vec3d(s.x[i].x(), s.x[i].y(), s.x[i].z()));
      EXPECT_LT(sa.getValue(c), 0.0f);
    }
  const openvdb::Coord far = xf.worldToIndexNodeCentered(openvdb::Vec3d(0.39, 0.39, 0.01));
  EXPECT_GT(sa.getValue(far), 0.0f);
  // The zero crossing lies a sphere radius outside the particles; the active
  // band reaches its half width (3 voxels) beyond that.
  const openvdb::CoordBBox sb = surface->evalActiveVoxelBoundingBox();
  const double hs = ss.voxel_size, reach = ss.radius + 3 * hs;
  for (int d = 0; d < 3; ++d) {
    EXPECT_NEAR(sb.min()[d] * hs, pb.lo[d] - reach, 2 * hs) << d;
    EXPECT_NEAR(sb.max()[d] * hs, pb.hi[d] + reach, 2 * hs) << d;
  }
}

// The level set is a narrow band of true distance, not the union of spheres
// ParticlesToLevelSet rasterises (whose inside is all active and only a few
// millimetres deep): inside the band it falls one metre per metre into the
// material, and deeper in it is inactive at minus the band's width.
TEST_F(VdbExport, SurfaceIsANarrowBandOfDistance) {
  const fs::path dir = test::tempDir("vdb_band");
  const World w = movingWorld(dir);
  const VdbFrameInfo info = vdbInfo(0.02, true);
  writeVolumesVdb((dir / "s.vdb").string(), w, info);
  openvdb::io::File file((dir / "s.vdb").string());
  file.open();
  auto surface = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("surface"));
  file.close();
  const double hs = surface->voxelSize()[0];
  const auto& xf = surface->transform();
  auto sa = surface->getConstAccessor();
  auto at = [&](double x, double y, double z) {
    return sa.getValue(xf.worldToIndexNodeCentered(openvdb::Vec3d(x, y, z)));
  };
  // The jelly cube spans y 0.05-0.17: its centre is deep inside the band.
  const openvdb::Coord centre = xf.worldToIndexNodeCentered(openvdb::Vec3d(0.10, 0.11, 0.09));
  EXPECT_FALSE(sa.isValueOn(centre));
  EXPECT_NEAR(sa.getValue(centre), -3.0 * hs, 1e-6);
  // Down through the top face, one voxel apart, both inside the band.
  const double top = 0.17, step = hs;
  const double slope = (at(0.10, top - 0.5 * hs, 0.09) - at(0.10, top - 0.5 * hs - step, 0.09)) / step;
  EXPECT_NEAR(slope, 1.0, 0.1);
  // Most of the cube's bounding box is inactive.
  const openvdb::CoordBBox box = surface->evalActiveVoxelBoundingBox();
  const double fraction = double(surface->activeVoxelCount()) / double(box.volume());
  std::printf("surface: slope %.3f inside the band, %.1f%% of its bounding box active\n", slope,
              100 * fraction);
  EXPECT_LT(fraction, 0.6);
}

// The splat sums in fixed point: the particles in another order, or split
// in two parts whose voxels are added up (as a split run's processes
// splat theirs), give the same voxels and the same file. Float sums in
// particle order differ in the last bits.
TEST_F(VdbExport, VolumesDoNotDependOnTheParticlesOrderOrSplit) {
  const fs::path dir = test::tempDir("vdb_order");
  const World w = movingWorld(dir);
  const VdbFrameInfo info = vdbInfo(0.02);
  writeVolumesVdb((dir / "in_order.vdb").string(), w, info);
  // Reversed, set by set.
  World reversed = w;
  for (ParticleSet& s : reversed.sets) {
    std::reverse(s.x.begin(), s.x.end());
    std::reverse(s.v.begin(), s.v.end());
  }
  writeVolumesVdb((dir / "reversed.vdb").string(), reversed, info);
  EXPECT_TRUE(slurp(dir / "in_order.vdb") == slurp(dir / "reversed.vdb"));
  // Split in two: every other particle in each part, one scale for both.
  double mass, momentum;
  largestMassAndMomentum(w, mass, momentum);
  const VolumeScale scale = volumeScale(mass, momentum);
  World part[2] = {w, w};
  for (size_t k = 0; k < w.sets.size(); ++k)
    for (int p = 0; p < 2; ++p) {
      ParticleSet& s = part[p].sets[k];
      s.x.clear();
      s.v.clear();
      for (size_t i = size_t(p); i < w.sets[k].size(); i += 2) {
        s.x.push_back(w.sets[k].x[i]);
        s.v.push_back(w.sets[k].v[i]);
      }
    }
  std::vector<VoxelSum> sums = splatVolumeSums(part[1], info.voxel_size, scale);
  const std::vector<VoxelSum> first = splatVolumeSums(part[0], info.voxel_size, scale);
  sums.insert(sums.end(), first.begin(), first.end());
  addVolumeSums(sums);
  const std::vector<VoxelSum> whole = splatVolumeSums(w, info.voxel_size, scale);
  ASSERT_EQ(sums.size(), whole.size());
  EXPECT_EQ(0, std::memcmp(sums.data(), whole.data(), sums.size() * sizeof(VoxelSum)));
  writeVolumesVdb((dir / "parts.vdb").string(), sums, scale, w, info);
  EXPECT_TRUE(slurp(dir / "in_order.vdb") == slurp(dir / "parts.vdb"));
}

TEST_F(VdbExport, SameParticlesSameBytesAndConfigurableVoxelSize) {
  const fs::path dir = test::tempDir("vdb_bytes");
  const World w = movingWorld(dir);
  const VdbFrameInfo info = vdbInfo(0.013, true);
  writeVolumesVdb((dir / "a.vdb").string(), w, info);
  writeVolumesVdb((dir / "b.vdb").string(), w, info);
  const std::string a = slurp(dir / "a.vdb"), b = slurp(dir / "b.vdb");
  ASSERT_GT(a.size(), 100u);
  EXPECT_TRUE(a == b) << "two writes of the same particles differ";
  // No temporary left behind.
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();

  openvdb::io::File file((dir / "a.vdb").string());
  file.open();
  auto density = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("density"));
  file.close();
  EXPECT_NEAR(density->voxelSize()[0], 0.013, 1e-12);
  double mass = 0.0;
  for (auto it = density->cbeginValueOn(); it; ++it) mass += double(*it) * std::pow(0.013, 3);
  EXPECT_NEAR(mass, test::moments(w).mass, 1e-5 * test::moments(w).mass);
}

TEST_F(VdbExport, VdbPrintReadsTheFile) {
  const fs::path dir = test::tempDir("vdb_print");
  const World w = movingWorld(dir);
  const VdbFrameInfo info = vdbInfo(0.02);
  writeVolumesVdb((dir / "d.vdb").string(), w, info);
  const std::string cmd = "vdb_print -l " + (dir / "d.vdb").string() + " >" +
                          (dir / "out.txt").string() + " 2>&1";
  const int raw = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(raw));
  ASSERT_NE(WEXITSTATUS(raw), 127) << "vdb_print not found: scripts/setup.sh installs libopenvdb-tools";
  EXPECT_EQ(WEXITSTATUS(raw), 0) << slurp(dir / "out.txt");
  const std::string out = slurp(dir / "out.txt");
  EXPECT_NE(out.find("density"), std::string::npos) << out;
  EXPECT_NE(out.find("vec3s"), std::string::npos) << out;
}

// A minimal binary little-endian PLY reader: header, then records of the
// declared scalar properties, every value widened to double.
struct PlyData {
  std::vector<std::string> names;
  std::vector<std::vector<double>> rows;
  std::string comment;
};

PlyData readPly(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  PlyData d;
  std::vector<std::string> types;
  size_t count = 0;
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "ply");
  while (std::getline(in, line) && line != "end_header") {
    std::istringstream w(line);
    std::string key;
    w >> key;
    if (key == "format") {
      std::string f;
      w >> f;
      EXPECT_EQ(f, "binary_little_endian");
    } else if (key == "element") {
      std::string what;
      w >> what >> count;
      EXPECT_EQ(what, "vertex");
    } else if (key == "property") {
      std::string type, name;
      w >> type >> name;
      types.push_back(type);
      d.names.push_back(name);
    } else if (key == "comment") {
      d.comment = line;
    }
  }
  for (size_t r = 0; r < count; ++r) {
    std::vector<double> row;
    for (const std::string& t : types) {
      unsigned char b[4];
      in.read(reinterpret_cast<char*>(b), 4);
      const uint32_t u = uint32_t(b[0]) | uint32_t(b[1]) << 8 | uint32_t(b[2]) << 16 |
                         uint32_t(b[3]) << 24;
      if (t == "float") {
        float f;
        std::memcpy(&f, &u, 4);
        row.push_back(f);
      } else if (t == "int") {
        row.push_back(double(int32_t(u)));
      } else {
        ADD_FAILURE() << "unexpected property type " << t;
      }
    }
    d.rows.push_back(row);
  }
  EXPECT_TRUE(in.good());
  in.peek();
  EXPECT_TRUE(in.eof()) << "bytes after the last vertex";
  return d;
}

TEST(PlyExport, IndependentReaderSeesTheParticles) {
  const fs::path dir = test::tempDir("ply_export");
  const World w = movingWorld(dir);
  writeParticlesPly((dir / "p.ply").string(), w);
  const PlyData d = readPly(dir / "p.ply");
  const std::vector<std::string> expected{"x", "y", "z", "vx", "vy", "vz", "object", "J", "id"};
  ASSERT_EQ(d.names, expected);
  ASSERT_EQ(d.rows.size(), w.particleCount());
  size_t r = 0;
  ParticleBounds read;
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i, ++r) {
      const std::vector<double>& row = d.rows[r];
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(row[k], s.x[i][k]);
        EXPECT_EQ(row[3 + k], s.v[i][k]);
      }
      EXPECT_EQ(row[6], s.object[i]);
      EXPECT_EQ(row[7], s.volumeRatio(i));
      EXPECT_EQ(row[8], s.id[i]);
      read.lo = read.lo.cwiseMin(Vec3d(row[0], row[1], row[2]));
      read.hi = read.hi.cwiseMax(Vec3d(row[0], row[1], row[2]));
    }
  const ParticleBounds pb = bounds(w);
  EXPECT_EQ(read.lo, pb.lo);
  EXPECT_EQ(read.hi, pb.hi);
  EXPECT_GT(pb.lo.minCoeff(), 0.0);
  EXPECT_LT(pb.hi.maxCoeff(), 0.4);
}

// Checkpoints: a round trip restores every array bit for bit; damage is caught.
TEST(CheckpointFile, RoundTripAndDamage) {
  const fs::path dir = test::tempDir("checkpoint_file");
  World w = movingWorld(dir);
  Solver solver(w);
  solver.advanceTo(0.13);
  const StepRecord rec{17, 1e-4, 2e-3, 12345};
  const std::string path = (dir / "state.0002.bin").string();
  writeCheckpoint(path, 2, "fnv1a64:0123456789abcdef", w, solver, rec);

  Checkpoint c = readCheckpoint(path);
  EXPECT_EQ(c.frame, 2);
  EXPECT_EQ(c.scene_hash, "fnv1a64:0123456789abcdef");
  EXPECT_EQ(c.time, w.time);
  EXPECT_EQ(c.steps, w.steps);
  EXPECT_EQ(c.record.steps, 17);
  EXPECT_EQ(c.record.particle_steps, 12345u);
  EXPECT_EQ(c.solver.max_speed, solver.state().max_speed);
  World fresh = movingWorld(dir);
  Solver fresh_solver(fresh);
  restoreCheckpoint(std::move(c), fresh, fresh_solver);
  ASSERT_EQ(fresh.sets.size(), w.sets.size());
  for (size_t k = 0; k < w.sets.size(); ++k) {
    const ParticleSet &a = w.sets[k], &b = fresh.sets[k];
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(0, std::memcmp(a.x.data(), b.x.data(), a.size() * sizeof(Vec3f)));
    EXPECT_EQ(0, std::memcmp(a.v.data(), b.v.data(), a.size() * sizeof(Vec3f)));
    EXPECT_EQ(0, std::memcmp(a.C.data(), b.C.data(), a.size() * sizeof(Mat3f)));
    ASSERT_EQ(a.F.size(), b.F.size());
    if (!a.F.empty()) {  // water has no F (and memcmp may not take null pointers)
      EXPECT_EQ(0, std::memcmp(a.F.data(), b.F.data(), a.F.size() * sizeof(Mat3f)));
    }
    EXPECT_EQ(a.J, b.J);
    EXPECT_EQ(a.id, b.id);
    EXPECT_EQ(a.object, b.object);
  }
  EXPECT_EQ(fresh.time, w.time);
  EXPECT_EQ(fresh.steps, w.steps);
  EXPECT_EQ(fresh_solver.stableDt(), solver.stableDt());

  // Truncated, a flipped byte, and another format: each refused with a reason.
  const std::string bytes = slurp(path);
  auto damaged = [&](const std::string& content) {
    const std::string p = (dir / "damaged.bin").string();
    std::ofstream(p, std::ios::binary) << content;
    try {
      readCheckpoint(p);
    } catch (const CheckpointError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(damaged(bytes.substr(0, bytes.size() / 2)).find("truncated"), std::string::npos);
  std::string flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x10;
  EXPECT_NE(damaged(flipped).find("checksum"), std::string::npos);
  std::string other = bytes;
  other[8] = 99;  // format version
  EXPECT_NE(damaged(other).find("version"), std::string::npos);
  EXPECT_NE(damaged("").find("truncated"), std::string::npos);
}

}  // namespace
}  // namespace triad
