#include "import/mesh_loader.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <limits>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include <Eigen/Geometry>

#include <assimp/BaseImporter.h>
#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <nlohmann/json.hpp>

#include "import/mesh_precheck.h"
#include "sim/errors.h"

// assimp as Debian builds it keeps its internal checks (ai_assert) on, and a
// failed one aborts the process: one corrupt file would take a whole run
// down (fuzz/fuzz_mesh.cpp found a glTF 1.0 primitive whose index accessor
// has no valid data, which aborts in glTFImporter). The library's own hook
// for this (setAiAssertHandler) is not exported by that build, but every
// check calls the handler through this exported symbol, which the program's
// own definition interposes. It throws instead: assimp's importers catch
// std::exception and report a failed import, and ApplyPostProcessing
// returns no scene; loadMesh then names the failed check.
namespace Assimp {
void aiAssertViolation(const char* expression, const char* file, int line);
}

namespace {
thread_local std::string assimp_failed_check;
}

void Assimp::aiAssertViolation(const char* expression, const char* file, int line) {
  std::string where = file ? file : "?";
  const size_t slash = where.find_last_of('/');
  if (slash != std::string::npos) where.erase(0, slash + 1);
  assimp_failed_check = "assimp's internal check failed (" + std::string(expression ? expression : "?") +
                        " at " + where + ":" + std::to_string(line) + ")";
  throw std::runtime_error(assimp_failed_check);
}

namespace triad {

namespace {

std::string plural(size_t n, const char* one, const char* many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

struct Vec3Hash {
  size_t operator()(const std::array<double, 3>& a) const {
    uint64_t h = 1469598103934665603ull;
    for (double v : a) {
      if (v == 0.0) v = 0.0;  // +0 and -0 are the same position
      uint64_t bits;
      std::memcpy(&bits, &v, sizeof bits);
      h = (h ^ bits) * 1099511628211ull;
      h ^= h >> 29;
    }
    return size_t(h);
  }
};

// Union-find over triangles.
struct DisjointSets {
  std::vector<int> parent;
  explicit DisjointSets(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  void unite(int a, int b) { parent[find(a)] = find(b); }
};

// The scene graph as assimp left it is checked as it is walked: counts
// without arrays, missing children and hierarchies too deep to be a tree
// are refused, naming the fault.
void collectNode(const aiScene* scene, const aiNode* node, const aiMatrix4x4& parent,
                 TriangleMesh& out, size_t& non_triangles, const std::string& path, int depth = 0) {
  auto invalid = [&](const std::string& why) { return InputError(path, "invalid mesh: " + why); };
  if (depth > 1000) throw invalid("the node hierarchy is more than 1000 levels deep (a cycle?)");
  if ((node->mNumMeshes && !node->mMeshes) || (node->mNumChildren && !node->mChildren))
    throw invalid("a node counts meshes or children it does not have");
  const aiMatrix4x4 m = parent * node->mTransformation;
  for (unsigned k = 0; k < node->mNumMeshes; ++k) {
    if (node->mMeshes[k] >= scene->mNumMeshes)
      throw InputError(path, "invalid mesh: a node refers to a mesh that does not exist");
    const aiMesh* mesh = scene->mMeshes[node->mMeshes[k]];
    if (!mesh || (mesh->mNumVertices && !mesh->mVertices) || (mesh->mNumFaces && !mesh->mFaces))
      throw invalid("mesh " + std::to_string(node->mMeshes[k]) +
                    " counts vertices or faces it does not have");
    const int base = static_cast<int>(out.positions.size());
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D p = m * mesh->mVertices[v];
      out.positions.emplace_back(p.x, p.y, p.z);
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices && !face.mIndices)
        throw invalid("face " + std::to_string(f) + " of mesh " +
                      std::to_string(node->mMeshes[k]) + " counts indices it does not have");
      if (face.mNumIndices != 3) {
        ++non_triangles;
        continue;
      }
      std::array<int, 3> t;
      for (int c = 0; c < 3; ++c) {
        if (face.mIndices[c] >= mesh->mNumVertices)
          throw InputError(path, "invalid mesh: face " + std::to_string(f) + " of mesh " +
                                     std::to_string(node->mMeshes[k]) + " uses vertex index " +
                                     std::to_string(face.mIndices[c]) + ", but the mesh has only " +
                                     std::to_string(mesh->mNumVertices) + " vertices");
        t[c] = base + static_cast<int>(face.mIndices[c]);
      }
      out.triangles.push_back(t);
    }
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) {
    if (!node->mChildren[c]) throw invalid("a node's child is missing");
    collectNode(scene, node->mChildren[c], m, out, non_triangles, path, depth + 1);
  }
}

// Merges vertices at exactly the same position; returns how many were merged.
size_t weldVertices(TriangleMesh& mesh) {
  std::unordered_map<std::array<double, 3>, int, Vec3Hash> index;
  index.reserve(mesh.positions.size());
  std::vector<int> remap(mesh.positions.size());
  std::vector<Vec3d> kept;
  kept.reserve(mesh.positions.size());
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    const Vec3d& p = mesh.positions[v];
    std::array<double, 3> key{p.x() == 0 ? 0.0 : p.x(), p.y() == 0 ? 0.0 : p.y(),
                              p.z() == 0 ? 0.0 : p.z()};
    auto [it, inserted] = index.try_emplace(key, static_cast<int>(kept.size()));
    if (inserted) kept.push_back(p);
    remap[v] = it->second;
  }
  const size_t merged = mesh.positions.size() - kept.size();
  mesh.positions = std::move(kept);
  for (auto& t : mesh.triangles)
    for (int& i : t) i = remap[i];
  return merged;
}

}  // namespace

void TriangleMesh::bounds(Vec3d& lo, Vec3d& hi) const {
  lo = Vec3d::Constant(std::numeric_limits<double>::infinity());
  hi = -lo;
  for (const Vec3d& p : positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
}

double TriangleMesh::signedVolume() const {
  double v = 0.0;
  for (const auto& t : triangles)
    v += positions[t[0]].dot(positions[t[1]].cross(positions[t[2]]));
  return v / 6.0;
}

Vec3d placePoint(const MeshDesc& desc, const Vec3d& p) {
  return Vec3d(desc.translate[0], desc.translate[1], desc.translate[2]) +
         eulerXYZDegrees(desc.rotate_deg) * (desc.scale * p);
}

void repairMesh(TriangleMesh& mesh, MeshLoadResult& report) {
  std::vector<std::string>& warn = report.warnings;
  // Degenerate triangles (a vertex used twice) carry no surface.
  const size_t before = mesh.triangles.size();
  mesh.triangles.erase(std::remove_if(mesh.triangles.begin(), mesh.triangles.end(),
                                      [](const std::array<int, 3>& t) {
                                        return t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
                                      }),
                       mesh.triangles.end());
  if (mesh.triangles.size() != before)
    warn.push_back(plural(before - mesh.triangles.size(), "degenerate triangle", "degenerate triangles") +
                   " (a vertex used twice) removed");
  const int nt = static_cast<int>(mesh.triangles.size());
  if (nt == 0) return;

  // Undirected edges, sorted, so that each edge's uses are adjacent.
  struct EdgeUse {
    uint64_t key;
    int tri;
    bool forward;  // the triangle runs the edge from the smaller to the larger index
  };
  auto edgeUses = [&]() {
    std::vector<EdgeUse> uses;
    uses.reserve(mesh.triangles.size() * 3);
    for (int t = 0; t < int(mesh.triangles.size()); ++t)
      for (int c = 0; c < 3; ++c) {
        const uint32_t a = mesh.triangles[t][c], b = mesh.triangles[t][(c + 1) % 3];
        const uint32_t lo = std::min(a, b), hi = std::max(a, b);
        uses.push_back({(uint64_t(lo) << 32) | hi, t, a < b});
      }
    std::sort(uses.begin(), uses.end(),
              [](const EdgeUse& x, const EdgeUse& y) { return x.key < y.key || (x.key == y.key && x.tri < y.tri); });
    return uses;
  };
  std::vector<EdgeUse> uses = edgeUses();

  // Manifold adjacency (edges used by exactly two triangles) for orienting;
  // every shared edge joins shells.
  std::vector<std::vector<std::pair<int, bool>>> adj(nt);  // (neighbour, same direction)
  DisjointSets shells(nt);
  size_t nonmanifold = 0;
  for (size_t i = 0; i < uses.size();) {
    size_t j = i;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    if (j - i == 2) {
      const bool same = uses[i].forward == uses[i + 1].forward;
      adj[uses[i].tri].push_back({uses[i + 1].tri, same});
      adj[uses[i + 1].tri].push_back({uses[i].tri, same});
    } else if (j - i > 2) {
      ++nonmanifold;
    }
    const EdgeUse* group = uses.data() + i;
    for (size_t k = 1; k < j - i; ++k) shells.unite(group[k - 1].tri, group[k].tri);
    i = j;
  }
  if (nonmanifold)
    warn.push_back(plural(nonmanifold, "non-manifold edge", "non-manifold edges") +
                   " (shared by more than two triangles)");

  // Consistent winding: breadth-first over manifold edges; within each
  // component keep the majority orientation.
  std::vector<int> comp(nt, -1);
  std::vector<char> flip(nt, 0);
  size_t reversed = 0;
  std::vector<int> queue;
  for (int seed = 0; seed < nt; ++seed) {
    if (comp[seed] >= 0) continue;
    queue.assign(1, seed);
    comp[seed] = seed;
    size_t flipped = 0;
    for (size_t q = 0; q < queue.size(); ++q) {
      const int t = queue[q];
      for (auto [n, same] : adj[t]) {
        if (comp[n] >= 0) continue;
        comp[n] = seed;
        flip[n] = char(flip[t] ^ (same ? 1 : 0));
        flipped += flip[n];
        queue.push_back(n);
      }
    }
    if (2 * flipped > queue.size()) {
      for (int t : queue) flip[t] ^= 1;
      flipped = queue.size() - flipped;
    }
    reversed += flipped;
  }
  for (int t = 0; t < nt; ++t)
    if (flip[t]) std::swap(mesh.triangles[t][1], mesh.triangles[t][2]);
  if (reversed)
    warn.push_back("inconsistent winding: " + plural(reversed, "triangle", "triangles") +
                   " reversed to match their neighbours");

  // Holes: loops of boundary edges (used once), closed by a fan around the
  // loop's centroid. With consistent winding the loop runs head to tail.
  std::unordered_multimap<int, std::pair<int, int>> boundary;  // from -> (to, triangle)
  for (size_t i = 0; i < uses.size();) {
    size_t j = i;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    if (j - i == 1) {
      const int t = uses[i].tri;
      for (int c = 0; c < 3; ++c) {
        const int a = mesh.triangles[t][c], b = mesh.triangles[t][(c + 1) % 3];
        const uint64_t key = (uint64_t(uint32_t(std::min(a, b))) << 32) | uint32_t(std::max(a, b));
        if (key == uses[i].key) boundary.insert({a, {b, t}});
      }
    }
    i = j;
  }
  report.boundary_edges = static_cast<int>(boundary.size());
  if (!boundary.empty()) {
    size_t loops = 0, closed_edges = 0;
    std::vector<std::vector<int>> fan_loops;
    std::vector<int> loop_tri;
    while (!boundary.empty()) {
      auto it = boundary.begin();
      const int start = it->first;
      std::vector<int> loop{start};
      int cur = it->second.first;
      loop_tri.assign(1, it->second.second);
      boundary.erase(it);
      bool ok = true;
      while (cur != start) {
        auto nx = boundary.find(cur);
        if (nx == boundary.end()) {
          ok = false;
          break;
        }
        loop.push_back(cur);
        loop_tri.push_back(nx->second.second);
        cur = nx->second.first;
        boundary.erase(nx);
      }
      if (!ok || loop.size() < 3) continue;
      ++loops;
      closed_edges += loop.size();
      Vec3d c = Vec3d::Zero();
      for (int v : loop) c += mesh.positions[v];
      c /= double(loop.size());
      const int ci = static_cast<int>(mesh.positions.size());
      mesh.positions.push_back(c);
      for (size_t e = 0; e < loop.size(); ++e) {
        const int a = loop[e], b = loop[(e + 1) % loop.size()];
        mesh.triangles.push_back({b, a, ci});
      }
      // The fan belongs to the shell it closes.
      shells.parent.resize(mesh.triangles.size());
      for (size_t k = shells.parent.size() - loop.size(); k < shells.parent.size(); ++k)
        shells.parent[k] = shells.find(loop_tri[0]);
    }
    std::string w = "open boundary: " + plural(report.boundary_edges, "edge", "edges") + " (holes)";
    if (loops) w += "; " + plural(loops, "hole", "holes") + " of " + std::to_string(closed_edges) +
                    " edges closed by a fan around their centroid";
    if (closed_edges < size_t(report.boundary_edges))
      w += "; " + std::to_string(report.boundary_edges - closed_edges) +
           " edges do not form closed loops and were left open";
    warn.push_back(w);
  }

  // Shells: turn each one outward (positive enclosed volume).
  const int all = static_cast<int>(mesh.triangles.size());
  shells.parent.resize(all);
  for (int t = 0; t < all; ++t)
    if (shells.parent[t] >= all) shells.parent[t] = t;
  std::unordered_map<int, double> volume;
  for (int t = 0; t < all; ++t) {
    const auto& tr = mesh.triangles[t];
    volume[shells.find(t)] +=
        mesh.positions[tr[0]].dot(mesh.positions[tr[1]].cross(mesh.positions[tr[2]]));
  }
  report.shells = static_cast<int>(volume.size());
  size_t inward = 0;
  for (auto& [root, v] : volume)
    if (v < 0) ++inward;
  if (inward) {
    for (int t = 0; t < all; ++t)
      if (volume[shells.find(t)] < 0) std::swap(mesh.triangles[t][1], mesh.triangles[t][2]);
    warn.push_back(plural(inward, "shell", "shells") + " facing inward reversed");
  }
  if (report.shells > 1)
    warn.push_back(std::to_string(report.shells) +
                   " separate shells (overlaps are merged: the inside is their union)");
}

namespace {

// Where several of assimp's importers claim a file's extension (glTF 1
// and 2 both claim .gltf) and none of them recognises the file, assimp
// 5.2 offers it to every importer it has, and the first that finds its
// own signature in it reads it: a PLY header inside a .gltf reached the
// PLY reader's endless loop past checkPly, and other readers of
// formats never meant here (found by fuzz/fuzz_mesh.cpp). So an importer
// keeps only the importers that claim the extension; a file that none of
// them reads is refused as unreadable, never guessed at.
void keepImportersFor(Assimp::Importer& importer, const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  if (!ext.empty()) ext.erase(0, 1);
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  std::vector<Assimp::BaseImporter*> others;
  for (size_t i = 0; i < importer.GetImporterCount(); ++i) {
    const aiImporterDesc* d = importer.GetImporterInfo(i);
    std::istringstream claimed(d && d->mFileExtensions ? d->mFileExtensions : "");
    bool claims = false;
    for (std::string e; claimed >> e;) claims = claims || e == ext;
    if (!claims) others.push_back(importer.GetImporter(i));
  }
  if (others.size() == importer.GetImporterCount())
    throw InputError(path, "cannot read the mesh: no importer reads files ending in \"." + ext +
                               "\" (OBJ, STL, PLY, glTF and the other formats of assimp by their "
                               "extension)");
  // Unregistered importers are no longer the Importer's to delete.
  for (Assimp::BaseImporter* p : others) {
    importer.UnregisterLoader(p);
    delete p;
  }
}

// assimp 5.2 (as Debian builds it, with its assertions on) aborts the
// process in its triangulation on a face without vertex indices (a binary
// PLY face whose list count is 0: found by fuzz/fuzz_mesh.cpp), and its
// validation lets such a face through. Refused here, before that step.
void checkFaces(const aiScene* scene, const std::string& path) {
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    for (unsigned f = 0; f < mesh->mNumFaces; ++f)
      if (mesh->mFaces[f].mNumIndices == 0)
        throw InputError(path, "invalid mesh: face " + std::to_string(f) + " of mesh " +
                                   std::to_string(m) + " has no vertex index");
  }
}

}  // namespace

MeshLoadResult loadMeshFile(const std::string& path) {
  MeshDesc d;
  d.path = d.resolved_path = path;
  return loadMesh(d);
}

MeshLoadResult loadMesh(const MeshDesc& desc) {
  const std::string& path = desc.resolved_path.empty() ? desc.path : desc.resolved_path;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    throw InputError(path, "cannot read the mesh: the file does not exist");
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(path, "cannot read the mesh: not a regular file");
  {
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext == ".ply") checkPly(path);
    if (ext == ".gltf" || ext == ".glb") checkGltfLayout(path);
    if (ext == ".gltf") checkGltfIndices(path);
  }
  if (!std::ifstream(path, std::ios::binary))
    throw InputError(path, "cannot read the mesh: the file cannot be opened");
  if (std::filesystem::file_size(path, ec) == 0)
    throw InputError(path, "cannot read the mesh: the file is empty");

  Assimp::Importer importer;
  keepImportersFor(importer, path);
  assimp_failed_check.clear();
  auto failed = [&]() {
    std::string why = importer.GetErrorString();
    if (why.empty() || why == "Unknown exception") why = assimp_failed_check;
    if (why.empty()) why = "unknown format or corrupt file";
    return InputError(path, "cannot read the mesh: " + why);
  };
  // Read and validate first; post-process only what passed checkFaces.
  const aiScene* scene = importer.ReadFile(path, aiProcess_ValidateDataStructure);
  if (!scene) throw failed();
  if (!scene->mRootNode || scene->mNumMeshes == 0)
    throw InputError(path, "the file holds no triangles (no mesh at all)");
  checkFaces(scene, path);
  // Triangulate polygons; join identical vertices; remove invalid data.
  // Winding is repaired here, never by assimp.
  scene = importer.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                       aiProcess_FindInvalidData);
  if (!scene) throw failed();

  MeshLoadResult r;
  size_t non_triangles = 0;
  collectNode(scene, scene->mRootNode, aiMatrix4x4(), r.mesh, non_triangles, path);
  r.input_triangles = r.mesh.triangles.size();
  if (r.mesh.triangles.empty())
    throw InputError(path, non_triangles
                               ? "the file holds no triangles, only " +
                                     plural(non_triangles, "point or line", "points or lines")
                               : std::string("the file holds no triangles"));
  if (non_triangles)
    r.warnings.push_back(plural(non_triangles, "point or line primitive", "point or line primitives") +
                         " ignored");
  for (const Vec3d& p : r.mesh.positions)
    if (!p.allFinite()) throw InputError(path, "invalid mesh: a vertex coordinate is not finite");

  const Mat3d rot = eulerXYZDegrees(desc.rotate_deg);
  const Vec3d tr(desc.translate[0], desc.translate[1], desc.translate[2]);
  for (Vec3d& p : r.mesh.positions) p = tr + rot * (desc.scale * p);

  const size_t merged = weldVertices(r.mesh);
  if (merged)
    r.warnings.push_back("duplicated vertices merged: " + plural(merged, "vertex", "vertices") +
                         " at the position of another");
  repairMesh(r.mesh, r);
  if (r.mesh.triangles.empty())
    throw InputError(path, "the file holds no triangles with three distinct vertices");
  return r;
}

TriangleMesh uvSphere(const Vec3d& c, double r, int nu, int nv) {
  TriangleMesh m;
  m.positions.push_back(c + Vec3d(0, r, 0));
  for (int j = 1; j < nv; ++j) {
    const double th = M_PI * j / nv;
    for (int i = 0; i < nu; ++i) {
      const double ph = 2 * M_PI * i / nu;
      m.positions.push_back(c + r * Vec3d(std::sin(th) * std::cos(ph), std::cos(th),
                                          std::sin(th) * std::sin(ph)));
    }
  }
  m.positions.push_back(c - Vec3d(0, r, 0));
  const int south = static_cast<int>(m.positions.size()) - 1;
  auto ring = [&](int j, int i) { return 1 + (j - 1) * nu + (i % nu); };
  for (int i = 0; i < nu; ++i) {
    m.triangles.push_back({0, ring(1, i + 1), ring(1, i)});
    m.triangles.push_back({south, ring(nv - 1, i), ring(nv - 1, i + 1)});
    for (int j = 1; j < nv - 1; ++j) {
      m.triangles.push_back({ring(j, i), ring(j, i + 1), ring(j + 1, i + 1)});
      m.triangles.push_back({ring(j, i), ring(j + 1, i + 1), ring(j + 1, i)});
    }
  }
  return m;
}

void saveMesh(const TriangleMesh& mesh, const std::string& path, const std::string& format,
              const std::array<double, 16>* node_transform) {
  aiScene scene;
  scene.mRootNode = new aiNode("root");
  scene.mMaterials = new aiMaterial*[1]{new aiMaterial()};
  scene.mNumMaterials = 1;
  auto* m = new aiMesh();
  scene.mMeshes = new aiMesh*[1]{m};
  scene.mNumMeshes = 1;
  m->mMaterialIndex = 0;
  m->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
  m->mNumVertices = static_cast<unsigned>(mesh.positions.size());
  m->mVertices = new aiVector3D[m->mNumVertices];
  for (unsigned v = 0; v < m->mNumVertices; ++v) {
    const Vec3d& p = mesh.positions[v];
    m->mVertices[v] = aiVector3D(float(p.x()), float(p.y()), float(p.z()));
  }
  m->mNumFaces = static_cast<unsigned>(mesh.triangles.size());
  m->mFaces = new aiFace[m->mNumFaces];
  for (unsigned f = 0; f < m->mNumFaces; ++f) {
    m->mFaces[f].mNumIndices = 3;
    m->mFaces[f].mIndices = new unsigned[3];
    for (int c = 0; c < 3; ++c) m->mFaces[f].mIndices[c] = unsigned(mesh.triangles[f][c]);
  }
  aiNode* holder = scene.mRootNode;
  if (node_transform) {
    holder = new aiNode("shape");
    const auto& t = *node_transform;
    holder->mTransformation = aiMatrix4x4(float(t[0]), float(t[1]), float(t[2]), float(t[3]),
                                          float(t[4]), float(t[5]), float(t[6]), float(t[7]),
                                          float(t[8]), float(t[9]), float(t[10]), float(t[11]),
                                          float(t[12]), float(t[13]), float(t[14]), float(t[15]));
    holder->mParent = scene.mRootNode;
    scene.mRootNode->mChildren = new aiNode*[1]{holder};
    scene.mRootNode->mNumChildren = 1;
  }
  holder->mMeshes = new unsigned[1]{0};
  holder->mNumMeshes = 1;
  Assimp::Exporter exporter;
  if (exporter.Export(&scene, format, path) != AI_SUCCESS)
    throw std::runtime_error("cannot write " + path + " as " + format + ": " +
                             exporter.GetErrorString());
}

}  // namespace triad
