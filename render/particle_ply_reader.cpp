#include "render/particle_ply_reader.h"

#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

#include "sim/errors.h"
#include "sim/ply_types.h"

namespace triad::render {

namespace {

struct Property {
  std::string name, type;
  int offset = 0;
};

// Reads an integer-valued property of any integer type (or float) at `p`.
bool readIndex(const Property& prop, const char* p, long long& out) {
  const std::string& t = prop.type;
  if (t == "int" || t == "int32") { int32_t v; std::memcpy(&v, p, 4); out = v; }
  else if (t == "uint" || t == "uint32") { uint32_t v; std::memcpy(&v, p, 4); out = v; }
  else if (t == "short" || t == "int16") { int16_t v; std::memcpy(&v, p, 2); out = v; }
  else if (t == "ushort" || t == "uint16") { uint16_t v; std::memcpy(&v, p, 2); out = v; }
  else if (t == "char" || t == "int8") { out = static_cast<signed char>(*p); }
  else if (t == "uchar" || t == "uint8") { out = static_cast<unsigned char>(*p); }
  else return false;
  return true;
}

}  // namespace

void readParticlesPly(const std::string& path, PreviewFrame& frame, std::vector<uint32_t>* ids) {
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "PLY reader assumes little-endian");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open the particle cache");
  auto bad = [&](const std::string& what) -> InputError { return InputError(path, what); };

  std::string line;
  if (!std::getline(in, line) || line != "ply") throw bad("not a PLY file (no 'ply' magic line)");
  long long count = -1;
  bool in_vertex = false, seen_other_element = false, ended = false;
  std::vector<Property> props;
  int stride = 0;
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
      std::string name;
      long long n = -1;
      ls >> name >> n;
      if (name == "vertex") {
        if (count >= 0 || seen_other_element) throw bad("the 'vertex' element must come first, once");
        if (!ls || n < 0) throw bad("bad vertex count in the header");
        count = n;
        in_vertex = true;
      } else {
        if (count < 0) throw bad("the 'vertex' element must come first");
        seen_other_element = true;
        in_vertex = false;
      }
    } else if (word == "property") {
      if (!in_vertex) continue;
      std::string type, name;
      ls >> type;
      if (type == "list") throw bad("list properties in the vertex element are not supported");
      ls >> name;
      const int size = plyTypeBytes(type);
      if (size == 0 || name.empty()) throw bad("bad property line '" + line + "'");
      props.push_back({name, type, stride});
      stride += size;
    } else if (word != "comment" && word != "obj_info" && !word.empty()) {
      throw bad("unexpected header line '" + line + "'");
    }
  }
  if (!ended) throw bad("no end_header (truncated or not a PLY file)");
  if (count < 0) throw bad("no vertex element");
  const Property* px = nullptr, *py = nullptr, *pz = nullptr, *pobj = nullptr, *pid = nullptr;
  for (const Property& p : props) {
    if (p.name == "x") px = &p;
    if (p.name == "y") py = &p;
    if (p.name == "z") pz = &p;
    if (p.name == "object") pobj = &p;
    if (p.name == "id") pid = &p;
  }
  for (const Property* p : {px, py, pz})
    if (!p || (p->type != "float" && p->type != "float32"))
      throw bad("the vertex element needs float properties x, y and z");
  if (!pobj || plyTypeBytes(pobj->type) > 4 || pobj->type == "float" || pobj->type == "float32")
    throw bad("the vertex element needs an integer property 'object'");
  if (ids && (!pid || plyTypeBytes(pid->type) != 4 || pid->type == "float" || pid->type == "float32"))
    throw bad("the vertex element needs a 32-bit integer property 'id'");

  const std::streamoff data_start = in.tellg();
  in.seekg(0, std::ios::end);
  const std::streamoff file_size = in.tellg();
  const unsigned long long need = static_cast<unsigned long long>(count) * unsigned(stride);
  if (data_start < 0 || static_cast<unsigned long long>(file_size - data_start) < need)
    throw bad("truncated: the header announces " + std::to_string(count) + " particles (" +
              std::to_string(need) + " bytes) but the file holds " +
              std::to_string(file_size - data_start) + " bytes of data");
  in.seekg(data_start);

  frame.xyz.resize(size_t(count) * 3);
  frame.object.resize(size_t(count));
  if (ids) ids->resize(size_t(count));
  std::vector<char> chunk;
  const size_t per_chunk = 65536;
  for (size_t done = 0; done < size_t(count);) {
    const size_t n = std::min(per_chunk, size_t(count) - done);
    chunk.resize(n * size_t(stride));
    if (!in.read(chunk.data(), std::streamsize(chunk.size()))) throw bad("read error in the particle data");
    for (size_t i = 0; i < n; ++i) {
      const char* rec = chunk.data() + i * size_t(stride);
      float* x = &frame.xyz[(done + i) * 3];
      std::memcpy(x + 0, rec + px->offset, 4);
      std::memcpy(x + 1, rec + py->offset, 4);
      std::memcpy(x + 2, rec + pz->offset, 4);
      long long obj = 0;
      readIndex(*pobj, rec + pobj->offset, obj);
      if (obj < 0 || obj > 65535)
        throw bad("particle " + std::to_string(done + i) + " has object index " + std::to_string(obj) +
                  " (expected 0..65535)");
      frame.object[done + i] = uint16_t(obj);
      if (ids) {
        long long id = 0;
        readIndex(*pid, rec + pid->offset, id);
        (*ids)[done + i] = uint32_t(id);
      }
    }
    done += n;
  }
}

}  // namespace triad::render
