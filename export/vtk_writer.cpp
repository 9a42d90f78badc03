#include "export/vtk_writer.h"

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <sstream>

#include "export/atomic_file.h"
#include "export/ply_writer.h"

namespace triad {

namespace {

// One array of the appended block: its XML attributes and its bytes.
struct Array {
  std::string xml;  // the DataArray element up to (without) offset="..."
  std::string bytes;
};

template <class T>
Array makeArray(const std::string& type, const std::string& name, int components,
                const std::vector<T>& values) {
  Array a;
  a.xml = "<DataArray type=\"" + type + "\"" + (name.empty() ? "" : " Name=\"" + name + "\"") +
          " NumberOfComponents=\"" + std::to_string(components) + "\" format=\"appended\"";
  a.bytes.assign(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  return a;
}

// The 64-bit cell arrays of n cells of `per` points each, numbered in order.
void sequentialCells(size_t n, int per, std::vector<int64_t>& connectivity,
                     std::vector<int64_t>& offsets) {
  connectivity.resize(n * size_t(per));
  offsets.resize(n);
  for (size_t i = 0; i < connectivity.size(); ++i) connectivity[i] = int64_t(i);
  for (size_t i = 0; i < n; ++i) offsets[i] = int64_t((i + 1) * size_t(per));
}

// A PolyData file of one piece: points, point data, and one cell section
// (`Verts` or `Polys`) given by its two arrays.
void writePolyData(const std::string& path, size_t points, const Array& positions,
                   const std::vector<Array>& point_data, const std::string& cell_kind, size_t cells,
                   const Array& connectivity, const Array& offsets) {
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "VTK writer assumes little-endian");
  writeFileAtomically(path, [&](std::ostream& out) {
    uint64_t offset = 0;
    auto element = [&](const Array& a, const char* indent) {
      out << indent << a.xml << " offset=\"" << offset << "\"/>\n";
      offset += sizeof(uint64_t) + a.bytes.size();
    };
    out << "<?xml version=\"1.0\"?>\n"
        << "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" "
           "header_type=\"UInt64\">\n"
        << "  <PolyData>\n"
        << "    <Piece NumberOfPoints=\"" << points << "\" NumberOfVerts=\""
        << (cell_kind == "Verts" ? cells : 0) << "\" NumberOfLines=\"0\" NumberOfStrips=\"0\" "
        << "NumberOfPolys=\"" << (cell_kind == "Polys" ? cells : 0) << "\">\n";
    out << "      <PointData>\n";
    for (const Array& a : point_data) element(a, "        ");
    out << "      </PointData>\n      <Points>\n";
    element(positions, "        ");
    out << "      </Points>\n      <" << cell_kind << ">\n";
    element(connectivity, "        ");
    element(offsets, "        ");
    out << "      </" << cell_kind << ">\n    </Piece>\n  </PolyData>\n"
        << "  <AppendedData encoding=\"raw\">\n   _";
    // Each array: its byte count (the header type), then its bytes, in the
    // order the offsets above were given.
    auto data = [&](const Array& a) {
      const uint64_t n = a.bytes.size();
      out.write(reinterpret_cast<const char*>(&n), sizeof(n));
      out.write(a.bytes.data(), std::streamsize(a.bytes.size()));
    };
    for (const Array& a : point_data) data(a);
    data(positions);
    data(connectivity);
    data(offsets);
    out << "\n  </AppendedData>\n</VTKFile>\n";
  });
}

std::string xmlEscaped(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '&')
      out += "&amp;";
    else if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '"')
      out += "&quot;";
    else
      out += c;
  }
  return out;
}

}  // namespace

void writeParticlesVtp(const std::string& path, const World& world) {
  const std::vector<ParticleRef> order = particlesById(world);
  const size_t n = order.size();
  std::vector<float> x(3 * n), v(3 * n), J(n);
  std::vector<uint32_t> id(n);
  std::vector<int32_t> object(n);
  for (size_t k = 0; k < n; ++k) {
    const ParticleSet& set = world.sets[order[k].set];
    const size_t i = order[k].index;
    for (int d = 0; d < 3; ++d) {
      x[3 * k + size_t(d)] = set.x[i][d];
      v[3 * k + size_t(d)] = set.v[i][d];
    }
    J[k] = set.volumeRatio(i);
    id[k] = set.id[i];
    object[k] = int32_t(set.object[i]);
  }
  std::vector<int64_t> connectivity, offsets;
  sequentialCells(n, 1, connectivity, offsets);
  writePolyData(path, n, makeArray("Float32", "", 3, x),
                {makeArray("Float32", "velocity", 3, v), makeArray("UInt32", "id", 1, id),
                 makeArray("Int32", "object", 1, object), makeArray("Float32", "J", 1, J)},
                "Verts", n, makeArray("Int64", "connectivity", 1, connectivity),
                makeArray("Int64", "offsets", 1, offsets));
}

void writeSurfaceVtp(const std::string& path, const TriSurface& surface) {
  std::vector<float> x;
  x.reserve(3 * surface.vertices.size());
  for (const Vec3f& p : surface.vertices) x.insert(x.end(), {p.x(), p.y(), p.z()});
  std::vector<int64_t> connectivity, offsets;
  connectivity.reserve(3 * surface.triangles.size());
  offsets.reserve(surface.triangles.size());
  for (const auto& t : surface.triangles) {
    connectivity.insert(connectivity.end(), {int64_t(t[0]), int64_t(t[1]), int64_t(t[2])});
    offsets.push_back(int64_t(connectivity.size()));
  }
  writePolyData(path, surface.vertices.size(), makeArray("Float32", "", 3, x), {}, "Polys",
                surface.triangles.size(), makeArray("Int64", "connectivity", 1, connectivity),
                makeArray("Int64", "offsets", 1, offsets));
}

void writePvd(const std::string& path, const std::vector<PvdEntry>& entries) {
  writeFileAtomically(path, [&](std::ostream& out) {
    out << "<?xml version=\"1.0\"?>\n"
        << "<VTKFile type=\"Collection\" version=\"1.0\" byte_order=\"LittleEndian\">\n"
        << "  <Collection>\n";
    for (const PvdEntry& e : entries) {
      char time[32];
      std::snprintf(time, sizeof(time), "%.9g", e.time);
      out << "    <DataSet timestep=\"" << time << "\" part=\"" << e.part << "\" name=\""
          << xmlEscaped(e.name) << "\" file=\"" << xmlEscaped(e.file) << "\"/>\n";
    }
    out << "  </Collection>\n</VTKFile>\n";
  });
}

}  // namespace triad
