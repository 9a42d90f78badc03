#include "export/body_writer.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "export/atomic_file.h"

namespace triad {

namespace {

// One triangle exactly as laid out in the file: the list count, then indices.
#pragma pack(push, 1)
struct PlyFace {
  uint8_t count;
  int32_t v[3];
};
#pragma pack(pop)
static_assert(sizeof(PlyFace) == 13, "PLY face must be packed");
static_assert(sizeof(Vec3f) == 12, "Eigen Vec3f must be packed");

// %.9g is enough to give back every float exactly, and a double to 1e-9
// relative: as much as a cache consumer can use. Negative zero is written
// as 0 so that a body at rest reads "0", not "-0".
void appendNumber(std::string& row, double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), ",%.9g", v == 0.0 ? 0.0 : v);
  row += buf;
}

std::vector<std::string> splitCommas(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  std::istringstream s(line);
  while (std::getline(s, field, ',')) fields.push_back(field);
  if (!line.empty() && line.back() == ',') fields.emplace_back();
  return fields;
}

bool isInteger(const std::string& s, int& out) {
  if (s.empty()) return false;
  char* end = nullptr;
  const long v = std::strtol(s.c_str(), &end, 10);
  if (*end != '\0' || v < 0 || v > std::numeric_limits<int>::max()) return false;
  out = int(v);
  return true;
}

bool isNumber(const std::string& s) {
  if (s.empty()) return false;
  char* end = nullptr;
  std::strtod(s.c_str(), &end);
  return *end == '\0';
}

}  // namespace

void writeSurfacePly(const std::string& path, const TriSurface& surface,
                     const std::string& comment) {
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "PLY writer assumes little-endian");
  // Faces are written as int indices: refuse what would not fit rather than
  // write a file that readers misinterpret.
  if (surface.vertices.size() > size_t(std::numeric_limits<int32_t>::max()))
    throw std::runtime_error(path + ": too many vertices for a PLY int index");
  std::vector<PlyFace> faces;
  faces.reserve(surface.triangles.size());
  for (const auto& t : surface.triangles)
    faces.push_back({3, {int32_t(t[0]), int32_t(t[1]), int32_t(t[2])}});
  writeFileAtomically(path, [&](std::ostream& out) {
    out << "ply\nformat binary_little_endian 1.0\n";
    if (!comment.empty()) out << "comment " << comment << "\n";
    out << "element vertex " << surface.vertices.size() << "\n"
        << "property float x\nproperty float y\nproperty float z\n"
        << "element face " << faces.size() << "\n"
        << "property list uchar int vertex_indices\n"
        << "end_header\n";
    out.write(reinterpret_cast<const char*>(surface.vertices.data()),
              std::streamsize(surface.vertices.size() * sizeof(Vec3f)));
    out.write(reinterpret_cast<const char*>(faces.data()),
              std::streamsize(faces.size() * sizeof(PlyFace)));
  });
}

void writeBodyPly(const std::string& path, const RigidBody& body, double time) {
  std::ostringstream comment;
  comment << "triad body " << body.name << " t=" << time;
  writeSurfacePly(path, worldSurface(body), comment.str());
}

void writeElasticPly(const std::string& path, const ElasticSolid& solid, double time) {
  std::ostringstream comment;
  comment << "triad body " << solid.name << " t=" << time;
  writeSurfacePly(path, solid.worldSurface(), comment.str());
}

std::string rigidStateRow(int frame, double time, const RigidBody& body) {
  std::string row = std::to_string(frame);
  appendNumber(row, time);
  row += "," + body.name;
  const Quatd q = body.orientation();
  const Vec3d w = body.omega();
  for (const double v : {body.state.x.x(), body.state.x.y(), body.state.x.z(), q.w(), q.x(),
                         q.y(), q.z(), body.state.v.x(), body.state.v.y(), body.state.v.z(),
                         w.x(), w.y(), w.z()})
    appendNumber(row, v);
  return row;
}

BodyTable::BodyTable(std::string header, int first_frame)
    : header_(std::move(header)),
      first_frame_(first_frame),
      columns_(size_t(std::count(header_.begin(), header_.end(), ',')) + 1) {}

void BodyTable::record(int frame, const std::vector<std::string>& rows) {
  while (!rows_.empty() && rows_.back().first >= frame) rows_.pop_back();
  for (const std::string& row : rows) rows_.emplace_back(frame, row);
}

std::string BodyTable::load(const std::string& path, int last_frame,
                            const std::vector<std::string>& names) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "missing";
  std::string line;
  if (!std::getline(in, line) || line != header_)
    return "not the expected table (header \"" + header_ + "\")";
  // Rows of frames first_frame..last_frame, in order, one per body; later ones are dropped.
  std::vector<std::pair<int, std::string>> rows;
  const size_t want = size_t(std::max(0, last_frame + 1 - first_frame_)) * names.size();
  for (size_t line_no = 2; rows.size() < want && std::getline(in, line); ++line_no) {
    if (in.eof()) return "line " + std::to_string(line_no) + " is cut short (no newline)";
    const std::vector<std::string> f = splitCommas(line);
    int frame = -1;
    bool numbers = f.size() == columns_ && isInteger(f[0], frame);
    for (size_t k = 1; numbers && k < f.size(); ++k) numbers = k == 2 || isNumber(f[k]);
    if (!numbers)
      return "line " + std::to_string(line_no) + " is not a row of " + std::to_string(columns_) +
             " values";
    const int expect_frame = first_frame_ + int(rows.size() / names.size());
    const std::string& expect_name = names[rows.size() % names.size()];
    if (frame != expect_frame || f[2] != expect_name)
      return "line " + std::to_string(line_no) + " is frame " + f[0] + " of \"" + f[2] +
             "\", expected frame " + std::to_string(expect_frame) + " of \"" + expect_name + "\"";
    rows.emplace_back(frame, line);
  }
  if (rows.size() < want)
    return "rows end before frame " + std::to_string(last_frame) + " is complete";
  rows_ = std::move(rows);
  return "";
}

void BodyTable::write(const std::string& path) const {
  writeFileAtomically(path, [&](std::ostream& out) {
    out << header_ << "\n";
    for (const auto& row : rows_) out << row.second << "\n";
  });
}

RigidStateLog::RigidStateLog()
    : BodyTable("frame,time,name,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz", 0) {}

void RigidStateLog::record(int frame, double time, const std::vector<RigidBody>& bodies) {
  std::vector<std::string> rows;
  for (const RigidBody& b : bodies) rows.push_back(rigidStateRow(frame, time, b));
  BodyTable::record(frame, rows);
}

BodyForceLog::BodyForceLog() : BodyTable("frame,time,name,fx,fy,fz,tx,ty,tz", 1) {}

void BodyForceLog::record(int frame, double time, const std::vector<RigidBody>& bodies,
                          const std::vector<BodyLoad>& loads) {
  std::vector<std::string> rows;
  for (size_t k = 0; k < bodies.size(); ++k) {
    std::string row = std::to_string(frame);
    appendNumber(row, time);
    row += "," + bodies[k].name;
    const Vec3d f = loads[k].force(), t = loads[k].torque();
    for (int d = 0; d < 3; ++d) appendNumber(row, f[d]);
    for (int d = 0; d < 3; ++d) appendNumber(row, t[d]);
    rows.push_back(row);
  }
  BodyTable::record(frame, rows);
}

}  // namespace triad
