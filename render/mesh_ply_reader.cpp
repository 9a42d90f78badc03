#include "render/mesh_ply_reader.h"

#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <vector>

#include "sim/errors.h"
#include "sim/ply_types.h"

namespace triad::render {

namespace {

bool isFloat(const std::string& t) {
  return t == "float" || t == "float32" || t == "double" || t == "float64";
}

// An unsigned integer of PLY type `t` at `p`; false for negative values.
bool readCount(const std::string& t, const char* p, uint64_t& out) {
  int64_t v = 0;
  if (t == "uchar" || t == "uint8") v = static_cast<unsigned char>(*p);
  else if (t == "char" || t == "int8") v = static_cast<signed char>(*p);
  else if (t == "ushort" || t == "uint16") { uint16_t x; std::memcpy(&x, p, 2); v = x; }
  else if (t == "short" || t == "int16") { int16_t x; std::memcpy(&x, p, 2); v = x; }
  else if (t == "uint" || t == "uint32") { uint32_t x; std::memcpy(&x, p, 4); v = x; }
  else if (t == "int" || t == "int32") { int32_t x; std::memcpy(&x, p, 4); v = x; }
  else return false;
  if (v < 0) return false;
  out = uint64_t(v);
  return true;
}

struct Scalar {
  std::string name, type;
};

}  // namespace

void readMeshPly(const std::string& path, PreviewMesh& mesh) {
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "PLY reader assumes little-endian");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open the body mesh");
  auto bad = [&](const std::string& what) { return InputError(path, what); };

  // Header: vertex element (scalars), then face element (scalars and one list).
  std::string line;
  if (!std::getline(in, line) || line != "ply") throw bad("not a PLY file (no 'ply' magic line)");
  long long vertices = -1, faces = -1;
  // Face scalars before and after the list (skipped), and the list's types.
  std::vector<Scalar> vprops, fprops_before, fprops_after;
  std::string list_count_type, list_index_type;
  bool has_list = false;
  std::string element;
  bool ended = false;
  for (int lines = 0; lines < 1000 && std::getline(in, line); ++lines) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (word == "end_header") {
      ended = true;
      break;
    }
    if (word == "format") {
      std::string fmt;
      ls >> fmt;
      if (fmt != "binary_little_endian")
        throw bad("PLY format '" + fmt + "' is not supported (expected binary_little_endian)");
    } else if (word == "element") {
      long long n = -1;
      ls >> element >> n;
      if (!ls || n < 0) throw bad("bad element line '" + line + "'");
      if (element == "vertex" && vertices < 0 && faces < 0) vertices = n;
      else if (element == "face" && vertices >= 0 && faces < 0) faces = n;
      else throw bad("expected a vertex element, then a face element, got '" + line + "'");
    } else if (word == "property") {
      std::string type, name;
      ls >> type;
      if (type == "list") {
        ls >> list_count_type >> list_index_type >> name;
        if (element != "face" || has_list || name.empty() || plyTypeBytes(list_count_type) == 0 ||
            isFloat(list_count_type) || plyTypeBytes(list_index_type) == 0 ||
            isFloat(list_index_type))
          throw bad("expected one integer list of vertex indices in the face element, got '" +
                    line + "'");
        has_list = true;
        continue;
      }
      ls >> name;
      if (plyTypeBytes(type) == 0 || name.empty()) throw bad("bad property line '" + line + "'");
      if (element == "vertex") vprops.push_back({name, type});
      else if (!has_list) fprops_before.push_back({name, type});
      else fprops_after.push_back({name, type});
    } else if (word != "comment" && word != "obj_info" && !word.empty()) {
      throw bad("unexpected header line '" + line + "'");
    }
  }
  if (!ended) throw bad("no end_header (truncated or not a PLY file)");
  if (vertices < 0 || faces < 0) throw bad("expected a vertex and a face element");
  if (!has_list) throw bad("the face element has no list of vertex indices");

  // Vertex layout: float x y z at their offsets in a fixed-size record.
  int stride = 0, ox = -1, oy = -1, oz = -1;
  for (const Scalar& p : vprops) {
    const bool f32 = p.type == "float" || p.type == "float32";
    if (p.name == "x" && f32) ox = stride;
    if (p.name == "y" && f32) oy = stride;
    if (p.name == "z" && f32) oz = stride;
    stride += plyTypeBytes(p.type);
  }
  if (ox < 0 || oy < 0 || oz < 0) throw bad("the vertex element needs float properties x, y and z");

  // The data, whole: body meshes are small.
  const std::vector<char> data((std::istreambuf_iterator<char>(in)),
                               std::istreambuf_iterator<char>());
  const char* p = data.data();
  const char* const end = data.data() + data.size();
  auto need = [&](size_t n, const char* what) {
    if (size_t(end - p) < n) throw bad(std::string("truncated in the ") + what);
  };
  need(size_t(vertices) * size_t(stride), "vertices");
  mesh.xyz.resize(size_t(vertices) * 3);
  for (long long i = 0; i < vertices; ++i, p += stride) {
    std::memcpy(&mesh.xyz[size_t(i) * 3 + 0], p + ox, 4);
    std::memcpy(&mesh.xyz[size_t(i) * 3 + 1], p + oy, 4);
    std::memcpy(&mesh.xyz[size_t(i) * 3 + 2], p + oz, 4);
  }
  auto skip = [&](const std::vector<Scalar>& props) {
    for (const Scalar& s : props) {
      need(size_t(plyTypeBytes(s.type)), "faces");
      p += plyTypeBytes(s.type);
    }
  };
  const int count_size = plyTypeBytes(list_count_type), index_size = plyTypeBytes(list_index_type);
  mesh.triangles.clear();
  mesh.triangles.reserve(size_t(faces) * 3);
  std::vector<uint32_t> poly;
  for (long long f = 0; f < faces; ++f) {
    skip(fprops_before);
    need(size_t(count_size), "faces");
    uint64_t n = 0;
    if (!readCount(list_count_type, p, n))
      throw bad("face " + std::to_string(f) + " has a negative vertex count");
    p += count_size;
    need(n * size_t(index_size), "faces");
    poly.resize(n);
    for (uint64_t k = 0; k < n; ++k, p += index_size) {
      uint64_t v = 0;
      if (!readCount(list_index_type, p, v) || v >= uint64_t(vertices))
        throw bad("face " + std::to_string(f) + " has a vertex index outside 0.." +
                  std::to_string(vertices - 1));
      poly[k] = uint32_t(v);
    }
    for (uint64_t k = 2; k < n; ++k)
      mesh.triangles.insert(mesh.triangles.end(), {poly[0], poly[k - 1], poly[k]});
    skip(fprops_after);
  }
  if (p != end) throw bad("data beyond the faces the header announces");
}

}  // namespace triad::render
