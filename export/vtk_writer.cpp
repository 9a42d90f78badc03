#include "export/vtk_writer.h"

#include <algorithm>
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

std::string arrayXml(const std::string& type, const std::string& name, int components) {
  return "<DataArray type=\"" + type + "\"" + (name.empty() ? "" : " Name=\"" + name + "\"") +
         " NumberOfComponents=\"" + std::to_string(components) + "\" format=\"appended\"";
}

template <class T>
Array makeArray(const std::string& type, const std::string& name, int components,
                const std::vector<T>& values) {
  Array a;
  a.xml = arrayXml(type, name, components);
  a.bytes.assign(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  return a;
}

// An array of the appended block as the file's XML describes it: its element
// and its length in bytes.
struct ArrayHead {
  std::string xml;
  uint64_t bytes = 0;
};

// A PolyData file of one piece: the XML before its appended data (up to and
// with the '_' that opens it), for point data, points and one cell section
// (`Verts` or `Polys`) given by its two arrays. The arrays' values follow
// in that order, each after its byte count (the header type), then kTail.
std::string polyDataHead(size_t points, const ArrayHead& positions,
                         const std::vector<ArrayHead>& point_data, const std::string& cell_kind,
                         size_t cells, const ArrayHead& connectivity, const ArrayHead& offsets) {
  std::ostringstream out;
  uint64_t offset = 0;
  auto element = [&](const ArrayHead& a, const char* indent) {
    out << indent << a.xml << " offset=\"" << offset << "\"/>\n";
    offset += sizeof(uint64_t) + a.bytes;
  };
  out << "<?xml version=\"1.0\"?>\n"
      << "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" "
         "header_type=\"UInt64\">\n"
      << "  <PolyData>\n"
      << "    <Piece NumberOfPoints=\"" << points << "\" NumberOfVerts=\""
      << (cell_kind == "Verts" ? cells : 0) << "\" NumberOfLines=\"0\" NumberOfStrips=\"0\" "
      << "NumberOfPolys=\"" << (cell_kind == "Polys" ? cells : 0) << "\">\n";
  out << "      <PointData>\n";
  for (const ArrayHead& a : point_data) element(a, "        ");
  out << "      </PointData>\n      <Points>\n";
  element(positions, "        ");
  out << "      </Points>\n      <" << cell_kind << ">\n";
  element(connectivity, "        ");
  element(offsets, "        ");
  out << "      </" << cell_kind << ">\n    </Piece>\n  </PolyData>\n"
      << "  <AppendedData encoding=\"raw\">\n   _";
  return out.str();
}
constexpr char kTail[] = "\n  </AppendedData>\n</VTKFile>\n";

ArrayHead headOf(const Array& a) {
  return {a.xml, a.bytes.size()};
}

void writePolyData(const std::string& path, size_t points, const Array& positions,
                   const std::vector<Array>& point_data, const std::string& cell_kind, size_t cells,
                   const Array& connectivity, const Array& offsets) {
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "VTK writer assumes little-endian");
  std::vector<ArrayHead> heads;
  for (const Array& a : point_data) heads.push_back(headOf(a));
  const std::string head = polyDataHead(points, headOf(positions), heads, cell_kind, cells,
                                        headOf(connectivity), headOf(offsets));
  writeFileAtomically(path, [&](std::ostream& out) {
    out << head;
    auto data = [&](const Array& a) {
      const uint64_t n = a.bytes.size();
      out.write(reinterpret_cast<const char*>(&n), sizeof(n));
      out.write(a.bytes.data(), std::streamsize(a.bytes.size()));
    };
    for (const Array& a : point_data) data(a);
    data(positions);
    data(connectivity);
    data(offsets);
    out << kTail;
  });
}

// The particle file's arrays, in the order of ParticlesVtpLayout::Array.
struct Kind {
  const char* type;
  const char* name;
  int components;
  uint64_t bytes;  // per entry
};
const Kind kParticleArrays[] = {{"Float32", "velocity", 3, 12}, {"UInt32", "id", 1, 4},
                                {"Int32", "object", 1, 4},      {"Float32", "J", 1, 4},
                                {"Float32", "", 3, 12},         {"Int64", "connectivity", 1, 8},
                                {"Int64", "offsets", 1, 8}};

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
  // The particles' records in id order, then each array packed from them a
  // chunk at a time, as every process of a split run packs its run of ids.
  std::vector<PlyParticle> records;
  records.reserve(world.particleCount());
  for (const ParticleRef& r : particlesById(world))
    records.push_back(plyParticle(world.sets[r.set], r.index));
  const ParticlesVtpLayout layout = particlesVtpLayout(records.size());
  writeFileAtomically(path, [&](std::ostream& out) {
    // The fixed pieces that lie before `at`, in file order.
    size_t piece = 0;
    auto fixedBefore = [&](uint64_t at) {
      for (; piece < layout.fixed.size() && layout.fixed[piece].first < at; ++piece)
        out << layout.fixed[piece].second;
    };
    std::vector<unsigned char> chunk;
    for (int a = 0; a < ParticlesVtpLayout::kArrays; ++a) {
      fixedBefore(layout.values[a]);
      const size_t per_chunk = std::max<size_t>(1, (size_t(1) << 20) / layout.entry[a]);
      for (size_t k = 0; k < records.size(); k += per_chunk) {
        const size_t count = std::min(per_chunk, records.size() - k);
        chunk.resize(count * layout.entry[a]);
        packParticlesVtp(ParticlesVtpLayout::Array(a), records.data() + k, count, k, chunk.data());
        out.write(reinterpret_cast<const char*>(chunk.data()), std::streamsize(chunk.size()));
      }
    }
    fixedBefore(layout.bytes);
  });
}

ParticlesVtpLayout particlesVtpLayout(size_t n) {
  ParticlesVtpLayout layout;
  ArrayHead heads[ParticlesVtpLayout::kArrays];
  for (int a = 0; a < ParticlesVtpLayout::kArrays; ++a) {
    const Kind& k = kParticleArrays[a];
    heads[a] = {arrayXml(k.type, k.name, k.components), uint64_t(n) * k.bytes};
  }
  using L = ParticlesVtpLayout;
  const std::string head = polyDataHead(
      n, heads[L::Points], {heads[L::Velocity], heads[L::Id], heads[L::Object], heads[L::J]},
      "Verts", n, heads[L::Connectivity], heads[L::Offsets]);
  layout.fixed.emplace_back(0, head);
  uint64_t at = head.size();
  for (int a = 0; a < ParticlesVtpLayout::kArrays; ++a) {
    const uint64_t bytes = heads[a].bytes;
    layout.fixed.emplace_back(at,
                              std::string(reinterpret_cast<const char*>(&bytes), sizeof(bytes)));
    layout.values[a] = at + sizeof(bytes);
    layout.entry[a] = kParticleArrays[a].bytes;
    at = layout.values[a] + bytes;
  }
  layout.fixed.emplace_back(at, kTail);
  layout.bytes = at + sizeof(kTail) - 1;
  return layout;
}

void packParticlesVtp(ParticlesVtpLayout::Array a, const PlyParticle* particles, size_t count,
                      uint64_t first, unsigned char* out) {
  using L = ParticlesVtpLayout;
  for (size_t k = 0; k < count; ++k) {
    const PlyParticle& p = particles[k];
    unsigned char* at = out + k * kParticleArrays[a].bytes;
    auto put = [&](const auto&... values) {
      size_t o = 0;
      ((std::memcpy(at + o, &values, sizeof(values)), o += sizeof(values)), ...);
    };
    switch (a) {
      case L::Velocity:
        put(p.vx, p.vy, p.vz);
        break;
      case L::Id:
        put(uint32_t(p.id));
        break;
      case L::Object:
        put(p.object);
        break;
      case L::J:
        put(p.J);
        break;
      case L::Points:
        put(p.x, p.y, p.z);
        break;
      case L::Connectivity:
        put(int64_t(first + k));
        break;
      case L::Offsets:
        put(int64_t(first + k + 1));
        break;
      case L::kArrays:
        break;
    }
  }
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
