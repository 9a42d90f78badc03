// Rigid body output: surface PLYs (export/body_writer, render/mesh_ply_reader),
// the state table and its resume semantics (RigidStateLog), checkpoints of
// body state (format version 2 on), and bodies in previews.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "export/body_writer.h"
#include "export/checkpoint.h"
#include "export/vtk_writer.h"
#include "render/mesh_ply_reader.h"
#include "render/preview_writer.h"
#include "scene_fixture.h"
#include "sim/errors.h"
#include "sim/solver.h"

namespace triad {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// An MPM cube, a free rigid box and a fixed rigid sphere.
json bodiesScene(const std::string& box_name = "crate") {
  json j = test::baseScene("bodies", {1, 1, 1}, 0.05);
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 5e4}, {"poisson_ratio", 0.3}};
  j["objects"] = {
      {{"name", "blob"}, {"kind", "mpm"}, {"material", "jelly"},
       {"shape", test::box({0.1, 0.1, 0.1}, {0.3, 0.3, 0.3})}},
      {{"name", box_name}, {"kind", "rigid"}, {"density", 500},
       {"shape", test::box({0.5, 0.5, 0.5}, {0.7, 0.6, 0.8})}},
      {{"name", "ball"}, {"kind", "rigid"}, {"density", 500}, {"fixed", true},
       {"shape", {{"sphere", {{"center", {0.5, 0.2, 0.5}}, {"radius", 0.1}}}}}}};
  return j;
}

// Moves and spins body `k` to an arbitrary, non-trivial state.
void perturb(World& w, size_t k, double s) {
  RigidState& st = w.bodies[k].state;
  st.x += Vec3d(0.01, -0.02, 0.03) * s;
  st.q_principal = (st.q_principal * Quatd(Eigen::AngleAxisd(0.3 * s, Vec3d(1, 2, 3).normalized())))
                       .normalized();
  st.v = Vec3d(0.1, -1.0 / 3.0, 0.25) * s;
  st.L = Vec3d(1e-3, -2e-4, 1.0 / 7.0) * s;
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream s(text);
  for (std::string l; std::getline(s, l);) out.push_back(l);
  return out;
}

TEST(BodyPly, WritesTheWorldSurfaceAndReadsItBack) {
  const fs::path dir = test::tempDir("body_ply");
  World w = test::loadWorld(dir, bodiesScene());
  ASSERT_EQ(w.bodies.size(), 2u);
  perturb(w, 0, 1.0);
  const RigidBody& crate = w.bodies[0];
  const std::string path = (dir / "crate.0001.ply").string();
  writeBodyPly(path, crate, 0.5);

  const std::string bytes = slurp(path);
  const std::string header =
      "ply\nformat binary_little_endian 1.0\ncomment triad body crate t=0.5\n"
      "element vertex 8\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 12\nproperty list uchar int vertex_indices\nend_header\n";
  ASSERT_EQ(bytes.substr(0, header.size()), header);
  EXPECT_EQ(bytes.size(), header.size() + 8 * 12 + 12 * 13);

  render::PreviewMesh m;
  render::readMeshPly(path, m);
  const TriSurface s = worldSurface(crate);
  ASSERT_EQ(m.xyz.size(), s.vertices.size() * 3);
  for (size_t i = 0; i < s.vertices.size(); ++i)
    for (int d = 0; d < 3; ++d) EXPECT_EQ(m.xyz[i * 3 + d], s.vertices[i][d]);
  ASSERT_EQ(m.triangles.size(), s.triangles.size() * 3);
  for (size_t t = 0; t < s.triangles.size(); ++t)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(m.triangles[t * 3 + c], s.triangles[t][c]);
}

TEST(MeshPly, SplitsPolygonsSkipsPropertiesAndRejectsBadFiles) {
  const fs::path dir = test::tempDir("mesh_ply");
  // One quad with a scalar before and after its list: two triangles.
  std::string quad =
      "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n"
      "property float y\nproperty float z\nproperty uchar red\nelement face 1\n"
      "property short tag\nproperty list uchar uint vertex_index\nproperty float w\nend_header\n";
  for (int i = 0; i < 4; ++i) {
    const float v[3] = {float(i & 1), float(i >> 1), 0.5f};
    quad.append(reinterpret_cast<const char*>(v), 12);
    quad.push_back(char(200));
  }
  const int16_t tag = 7;
  const uint32_t idx[4] = {0, 1, 3, 2};
  const float wgt = 1.0f;
  quad.append(reinterpret_cast<const char*>(&tag), 2);
  quad.push_back(char(4));
  quad.append(reinterpret_cast<const char*>(idx), 16);
  quad.append(reinterpret_cast<const char*>(&wgt), 4);
  std::ofstream(dir / "quad.ply", std::ios::binary) << quad;
  render::PreviewMesh m;
  render::readMeshPly((dir / "quad.ply").string(), m);
  EXPECT_EQ(m.triangles, (std::vector<uint32_t>{0, 1, 3, 0, 3, 2}));
  EXPECT_EQ(m.xyz.size(), 12u);
  EXPECT_EQ(m.xyz[9], 1.0f);  // vertex 3 = (1, 1, 0.5)

  // Truncated, another format, an index out of range, trailing bytes, absent.
  std::string out_of_range = quad;
  out_of_range[out_of_range.size() - 8] = 9;  // idx[3] = 9 > 3
  std::ofstream(dir / "cut.ply", std::ios::binary) << quad.substr(0, quad.size() - 5);
  std::ofstream(dir / "ascii.ply", std::ios::binary)
      << "ply\nformat ascii 1.0\nelement vertex 0\nend_header\n";
  std::ofstream(dir / "range.ply", std::ios::binary) << out_of_range;
  std::ofstream(dir / "long.ply", std::ios::binary) << quad + "xx";
  for (const char* bad : {"cut.ply", "ascii.ply", "range.ply", "long.ply", "missing.ply"}) {
    try {
      render::readMeshPly((dir / bad).string(), m);
      ADD_FAILURE() << bad << " was read";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
}

TEST(RigidStateLog, RowsHoldStateWithFullPrecisionAndNoNegativeZero) {
  const fs::path dir = test::tempDir("state_rows");
  World w = test::loadWorld(dir, bodiesScene());
  // At rest at t = 0: identity orientation, zero velocities written as 0.
  w.bodies[0].state.v = Vec3d(-0.0, 0.0, -0.0);
  const std::string row = rigidStateRow(0, 0.0, w.bodies[0]);
  EXPECT_EQ(row.find("-0,"), std::string::npos) << row;
  std::vector<std::string> f;
  std::istringstream s(row);
  for (std::string x; std::getline(s, x, ',');) f.push_back(x);
  ASSERT_EQ(f.size(), 16u) << row;
  EXPECT_EQ(f[0], "0");
  EXPECT_EQ(f[1], "0");
  EXPECT_EQ(f[2], "crate");
  EXPECT_NEAR(std::stod(f[3]), 0.6, 1e-6);
  EXPECT_NEAR(std::stod(f[4]), 0.55, 1e-6);
  EXPECT_NEAR(std::stod(f[5]), 0.65, 1e-6);
  EXPECT_NEAR(std::stod(f[6]), 1.0, 1e-12);
  for (int k = 7; k < 16; ++k) EXPECT_NEAR(std::stod(f[k]), 0.0, 1e-12) << k;

  // Moving: 9 significant digits of every value.
  const TriSurface rest = worldSurface(w.bodies[0]);
  const Vec3d x0 = w.bodies[0].state.x;
  perturb(w, 0, 1.0);
  const RigidBody& b = w.bodies[0];
  const std::string moving = rigidStateRow(7, 7 / 24.0, b);
  f.clear();
  std::istringstream s2(moving);
  for (std::string x; std::getline(s2, x, ',');) f.push_back(x);
  ASSERT_EQ(f.size(), 16u);
  EXPECT_EQ(f[1], "0.291666667");
  const Quatd q = b.orientation();
  const Vec3d omega = b.omega();
  const double expect[13] = {b.state.x.x(), b.state.x.y(), b.state.x.z(), q.w(), q.x(), q.y(),
                             q.z(), b.state.v.x(), b.state.v.y(), b.state.v.z(), omega.x(),
                             omega.y(), omega.z()};
  for (int k = 0; k < 13; ++k)
    EXPECT_NEAR(std::stod(f[3 + k]), expect[k], 1e-8 * std::max(1.0, std::abs(expect[k]))) << k;
  EXPECT_GT(omega.norm(), 0.0);
  // What the README promises: the frame-0 mesh moved by (p, q) is the mesh now.
  const TriSurface now = worldSurface(b);
  for (size_t i = 0; i < rest.vertices.size(); ++i) {
    const Vec3d r0 = rest.vertices[i].cast<double>();
    const Vec3d expect_now = b.state.x + q * (r0 - x0);
    EXPECT_LT((now.vertices[i].cast<double>() - expect_now).norm(), 1e-6) << i;
  }
  EXPECT_GT(std::abs(q.w() - 1.0), 1e-3) << "the test must rotate the body";
}

TEST(RigidStateLog, FramesWrittenAgainReplaceTheirRows) {
  const fs::path dir = test::tempDir("state_replace");
  const World w = test::loadWorld(dir, bodiesScene());
  RigidStateLog log;
  for (int f = 0; f <= 3; ++f) log.record(f, f / 24.0, w.bodies);
  EXPECT_EQ(log.rows(), 8u);
  EXPECT_EQ(log.lastFrame(), 3);
  log.record(2, 2 / 24.0, w.bodies);
  EXPECT_EQ(log.rows(), 6u);
  EXPECT_EQ(log.lastFrame(), 2);
  const std::string path = (dir / "rigid_states.csv").string();
  log.write(path);
  const std::vector<std::string> l = lines(slurp(path));
  ASSERT_EQ(l.size(), 7u);
  EXPECT_EQ(l[0], "frame,time,name,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz");
  EXPECT_EQ(l[5].substr(0, 15), "2,0.0833333333,");
}

TEST(RigidStateLog, LoadKeepsTheRowsUpToTheResumedFrameByteForByte) {
  const fs::path dir = test::tempDir("state_load");
  World w = test::loadWorld(dir, bodiesScene());
  const std::vector<std::string> names = {"crate", "ball"};
  RigidStateLog full;
  for (int f = 0; f <= 4; ++f) {
    perturb(w, 0, 0.1);  // values with many digits
    full.record(f, f / 24.0, w.bodies);
  }
  const std::string path = (dir / "full.csv").string();
  full.write(path);
  const std::vector<std::string> all = lines(slurp(path));
  ASSERT_EQ(all.size(), 11u);

  // Resumed after frame 2: rows of frames 0..2, then frame 3 recorded anew.
  RigidStateLog log;
  ASSERT_EQ(log.load(path, 2, names), "");
  EXPECT_EQ(log.rows(), 6u);
  const std::string kept = (dir / "kept.csv").string();
  log.write(kept);
  EXPECT_EQ(lines(slurp(kept)), std::vector<std::string>(all.begin(), all.begin() + 7));
  ASSERT_EQ(log.load(path, 4, names), "");
  log.write(kept);
  EXPECT_EQ(slurp(kept), slurp(path));

  // What is not a complete table of these bodies is refused, the log unchanged.
  auto refused = [&](const std::string& text, int frame, const std::vector<std::string>& n,
                     const std::string& why) {
    const std::string p = (dir / "bad.csv").string();
    std::ofstream(p, std::ios::binary) << text;
    const std::string err = log.load(p, frame, n);
    EXPECT_NE(err.find(why), std::string::npos) << "error: " << err << "\nexpected: " << why;
    EXPECT_EQ(log.rows(), 10u);
  };
  const std::string text = slurp(path);
  refused(text, 5, names, "before frame 5");
  refused(text, 2, {"ball", "crate"}, "expected frame 0 of \"ball\"");
  refused(text, 2, {"crate"}, "expected frame 1 of \"crate\"");
  refused("frame,time\n" + text.substr(text.find('\n') + 1), 1, names, "header");
  refused(text.substr(0, text.size() - 1), 4, names, "cut short");
  std::string bad_number = text;
  bad_number[bad_number.find(",crate,") + 7] = 'z';  // px "z.6..."
  refused(bad_number, 0, names, "not a row of 16 values");
  EXPECT_EQ(log.load((dir / "absent.csv").string(), 0, names), "missing");
  // A table cut after a complete row still gives the frames it holds.
  ASSERT_EQ(log.load(path, 1, names), "");
  EXPECT_EQ(log.rows(), 4u);
}

TEST(CheckpointBodies, RoundTripsRigidStateExactly) {
  const fs::path dir = test::tempDir("ckpt_bodies");
  World w = test::loadWorld(dir, bodiesScene());
  perturb(w, 0, 1.0);
  perturb(w, 1, -0.5);  // a fixed body's state is stored as it is
  w.time = 0.125;
  w.steps = 150;
  Solver solver(w);
  const std::string path = (dir / "state.0003.bin").string();
  writeCheckpoint(path, 3, "fnv1a64:0123456789abcdef", w, solver, solver.record());

  Checkpoint c = readCheckpoint(path);
  ASSERT_EQ(c.bodies.size(), 2u);
  EXPECT_EQ(c.bodies[0].first, "crate");
  EXPECT_EQ(c.bodies[1].first, "ball");
  World fresh = test::loadWorld(dir, bodiesScene());
  Solver fresh_solver(fresh);
  restoreCheckpoint(std::move(c), fresh, fresh_solver);
  for (size_t k = 0; k < 2; ++k) {
    const RigidState &a = w.bodies[k].state, &b = fresh.bodies[k].state;
    EXPECT_EQ(a.x, b.x) << k;
    EXPECT_EQ(a.q_principal.coeffs(), b.q_principal.coeffs()) << k;
    EXPECT_EQ(a.v, b.v) << k;
    EXPECT_EQ(a.L, b.L) << k;
  }
  EXPECT_EQ(fresh.time, 0.125);
  EXPECT_EQ(fresh.steps, 150);
}

TEST(CheckpointBodies, OtherBodiesAreRefusedAndNothingChanges) {
  const fs::path dir = test::tempDir("ckpt_bodies_other");
  World w = test::loadWorld(dir, bodiesScene());
  perturb(w, 0, 1.0);
  Solver solver(w);
  const std::string path = (dir / "state.0001.bin").string();
  writeCheckpoint(path, 1, "fnv1a64:0", w, solver, solver.record());

  auto refusal = [&](const json& scene) -> std::string {
    World other = test::loadWorld(dir, scene);
    const std::vector<Vec3f> before = other.sets[0].x;
    const Vec3d body_before = other.bodies.empty() ? Vec3d::Zero() : other.bodies[0].state.x;
    Solver s(other);
    try {
      restoreCheckpoint(readCheckpoint(path), other, s);
    } catch (const CheckpointError& e) {
      EXPECT_EQ(other.sets[0].x, before);
      if (!other.bodies.empty()) {
        EXPECT_EQ(other.bodies[0].state.x, body_before);
      }
      return e.what();
    }
    ADD_FAILURE() << "restored into another scene's world";
    return "";
  };
  const std::string renamed = refusal(bodiesScene("box"));
  EXPECT_NE(renamed.find("\"crate\""), std::string::npos) << renamed;
  EXPECT_NE(renamed.find("\"box\""), std::string::npos) << renamed;
  json fewer = bodiesScene();
  fewer["objects"].erase(2);
  const std::string count = refusal(fewer);
  EXPECT_NE(count.find("2 rigid bodies, the scene has 1"), std::string::npos) << count;

  // Version 1 files (no bodies) are refused by version.
  std::string bytes = slurp(path);
  bytes[8] = 1;
  std::ofstream(dir / "v1.bin", std::ios::binary) << bytes;
  try {
    readCheckpoint((dir / "v1.bin").string());
    ADD_FAILURE() << "version 1 read";
  } catch (const CheckpointError& e) {
    EXPECT_NE(std::string(e.what()).find("version 1, expected " + std::to_string(kCheckpointVersion)),
              std::string::npos)
        << e.what();
  }
}

// Pieces of a file summed in any order, cut anywhere (mid-word too), give
// the checksum of the whole; a flipped bit or two swapped words do not.
TEST(FileChecksum, PartsInAnyOrderAndAnyCutAddUpToTheWhole) {
  std::vector<unsigned char> bytes(1003);
  uint32_t state = 12345;
  for (unsigned char& b : bytes) b = uint8_t((state = state * 1664525u + 1013904223u) >> 24);
  FileChecksum whole;
  whole.append(bytes.data(), bytes.size());
  for (const std::vector<size_t>& cuts :
       {std::vector<size_t>{0, 1003}, {0, 5, 8, 13, 400, 1003}, {0, 3, 1000, 1003}}) {
    FileChecksum merged;
    for (size_t k = cuts.size() - 1; k > 0; --k) {  // last piece first
      FileChecksum part;
      part.add(cuts[k - 1], bytes.data() + cuts[k - 1], cuts[k] - cuts[k - 1]);
      merged.merge(part.part());
    }
    EXPECT_EQ(merged.value(bytes.size()), whole.value()) << cuts.size();
  }
  std::vector<unsigned char> flipped = bytes;
  flipped[517] ^= 0x10;
  FileChecksum f;
  f.append(flipped.data(), flipped.size());
  EXPECT_NE(f.value(), whole.value());
  std::vector<unsigned char> swapped = bytes;
  std::swap_ranges(swapped.begin() + 64, swapped.begin() + 72, swapped.begin() + 128);
  FileChecksum s;
  s.append(swapped.data(), swapped.size());
  EXPECT_NE(s.value(), whole.value());
  // The length counts: a zero byte more is another file.
  FileChecksum longer;
  longer.append(bytes.data(), bytes.size());
  const unsigned char zero = 0;
  longer.append(&zero, 1);
  EXPECT_NE(longer.value(), whole.value());
}

// bodiesScene() with a pool of water beside: two particle sets, one with F
// and one with J.
json bodiesAndPoolScene() {
  json scene = bodiesScene();
  scene["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}};
  scene["objects"].push_back({{"name", "pool"},
                              {"kind", "mpm"},
                              {"material", "water"},
                              {"shape", test::box({0.6, 0.1, 0.1}, {0.9, 0.2, 0.3})}});
  return scene;
}

// A split run's checkpoint: process 0 writes the layout's pieces and every
// process its particles at their places, each summing what it wrote. Done
// here for two shares of every set (one of them empty for one set): the
// bytes are those of one process's checkpoint of the whole world.
TEST(CheckpointLayout, SharesWrittenAtTheirPlacesMakeTheSingleProcessFile) {
  const fs::path dir = test::tempDir("ckpt_layout");
  World w = test::loadWorld(dir, bodiesAndPoolScene());
  ASSERT_EQ(w.sets.size(), 2u);
  perturb(w, 0, 1.0);
  w.time = 0.25;
  w.steps = 300;
  Solver solver(w);
  const SolverState st = solver.state();
  const std::string path = (dir / "state.0005.bin").string();
  writeCheckpoint(path, 5, "fnv1a64:feed", w, st, solver.record());
  const std::string expected = slurp(path);

  // Share 0: the first third of the jelly and none of the water; share 1 the rest.
  std::vector<uint64_t> counts, first1;
  for (const ParticleSet& s : w.sets) counts.push_back(s.size());
  first1 = {counts[0] / 3, 0};
  World share0 = w;
  for (size_t k = 0; k < 2; ++k) {
    ParticleSet& s = share0.sets[k];
    const size_t n = size_t(first1[k]);
    s.x.resize(n), s.v.resize(n), s.C.resize(n), s.id.resize(n), s.object.resize(n);
    if (!s.F.empty()) s.F.resize(n);
    if (!s.J.empty()) s.J.resize(n);
  }
  const CheckpointLayout layout =
      layoutCheckpoint(5, "fnv1a64:feed", share0, st, solver.record(), counts);
  ASSERT_EQ(layout.bytes, expected.size());
  std::string file(layout.bytes, '\0');
  auto put = [&](uint64_t offset, const void* p, size_t n, FileChecksum& part) {
    if (n == 0) return;
    std::memcpy(file.data() + offset, p, n);
    part.add(offset, p, n);
  };
  FileChecksum part0, part1;
  for (const CheckpointLayout::Piece& piece : layout.pieces)
    put(piece.offset, piece.bytes.data(), piece.bytes.size(), part0);
  for (size_t k = 0; k < 2; ++k) {
    const ParticleSet& s = w.sets[k];
    const void* data[7] = {s.x.data(), s.v.data(),  s.C.data(),     s.F.data(),
                           s.J.data(), s.id.data(), s.object.data()};
    const bool has[7] = {true, true, true, !s.F.empty(), !s.J.empty(), true, true};
    for (size_t a = 0; a < 7; ++a) {
      if (!has[a]) continue;
      const uint64_t e = kCheckpointEntryBytes[a], at = layout.arrays[k][a];
      const auto* bytes = static_cast<const unsigned char*>(data[a]);
      put(at, bytes, size_t(first1[k] * e), part0);
      put(at + first1[k] * e, bytes + first1[k] * e, size_t((counts[k] - first1[k]) * e), part1);
    }
  }
  FileChecksum sum;
  sum.merge(part1.part());
  sum.merge(part0.part());
  // The checksum covers all but the trailer, whose place the layout leaves.
  const std::array<unsigned char, 16> end = checkpointTrailer(sum, layout.bytes - 16);
  std::memcpy(file.data() + layout.bytes - 16, end.data(), 16);
  EXPECT_TRUE(file == expected);
  // And it reads back.
  std::ofstream(dir / "assembled.bin", std::ios::binary) << file;
  const Checkpoint c = readCheckpoint((dir / "assembled.bin").string());
  EXPECT_EQ(c.sets[0].x, w.sets[0].x);
  EXPECT_EQ(c.sets[1].J, w.sets[1].J);
}

// The particles' VTK file assembled from its layout, with each array's
// entries written in two runs of ids at their places (as two MPI processes
// write it), is the file the single writer makes.
TEST(ParticlesVtpLayout, RunsWrittenAtTheirPlacesMakeTheSingleWritersFile) {
  const fs::path dir = test::tempDir("vtp_layout");
  World w = test::loadWorld(dir, bodiesAndPoolScene());
  ASSERT_EQ(w.sets.size(), 2u);
  perturb(w, 0, 1.0);
  // Ids out of the sets' order: the file lists them by id.
  std::reverse(w.sets[1].id.begin(), w.sets[1].id.end());
  const std::string path = (dir / "particles.0003.vtp").string();
  writeParticlesVtp(path, w);
  const std::string expected = slurp(path);

  std::vector<PlyParticle> sorted;
  for (const ParticleRef& r : particlesById(w))
    sorted.push_back(plyParticle(w.sets[r.set], r.index));
  const size_t n = sorted.size(), cut = n / 3;
  const ParticlesVtpLayout layout = particlesVtpLayout(n);
  ASSERT_EQ(layout.bytes, expected.size());
  std::string file(layout.bytes, '\x55');
  for (const auto& [offset, bytes] : layout.fixed) file.replace(offset, bytes.size(), bytes);
  for (int a = 0; a < ParticlesVtpLayout::kArrays; ++a) {
    const auto array = ParticlesVtpLayout::Array(a);
    for (const auto& [first, count] : {std::pair{size_t(0), cut}, {cut, n - cut}}) {
      std::vector<unsigned char> part(count * layout.entry[a]);
      packParticlesVtp(array, sorted.data() + first, count, first, part.data());
      std::memcpy(file.data() + layout.values[a] + first * layout.entry[a], part.data(),
                  part.size());
    }
  }
  EXPECT_TRUE(file == expected);
}

TEST(PreviewBodies, FrameFromWorldDrawsEveryBodyInItsObjectColour) {
  const fs::path dir = test::tempDir("preview_bodies");
  World w = test::loadWorld(dir, bodiesScene());
  perturb(w, 0, 1.0);
  const render::PreviewFrame f = render::previewFrameFromWorld(w);
  EXPECT_EQ(f.object.size(), w.particleCount());
  ASSERT_EQ(f.meshes.size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    const TriSurface s = worldSurface(w.bodies[k]);
    const render::PreviewMesh& m = f.meshes[k];
    EXPECT_EQ(m.object, w.bodies[k].object);
    ASSERT_EQ(m.xyz.size(), s.vertices.size() * 3);
    EXPECT_EQ(0, std::memcmp(m.xyz.data(), s.vertices.data(), m.xyz.size() * sizeof(float)));
    EXPECT_EQ(m.triangles.size(), s.triangles.size() * 3);
  }
  EXPECT_EQ(f.meshes[0].object, 1);
  EXPECT_EQ(f.meshes[1].object, 2);
}

}  // namespace
}  // namespace triad
