// Checks of mesh files before assimp reads them (see mesh_precheck.h).
#include "import/mesh_precheck.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sim/errors.h"
#include "sim/ply_types.h"

namespace triad {

// assimp 5.2's PLY reader loops for ever on some malformed headers (an
// element without properties, a property before any element: found by
// fuzz/fuzz_mesh.cpp). A PLY file's header is checked here first, to its
// grammar: "ply", a format line, then comment, obj_info, element NAME
// COUNT, property TYPE NAME and property list TYPE TYPE NAME lines up to
// end_header, every element with at least one property, and no control
// character but tabs.
namespace {

struct PlyProperty {
  int count_bytes = 0;  // list: bytes of its count; 0 for a scalar
  int item_bytes = 0;
  std::string count_type, item_type;
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;
};

}  // namespace

void checkPly(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  auto fail = [&](int n, const std::string& why) {
    throw InputError(path, "not a valid PLY file: header line " + std::to_string(n) + ": " + why);
  };
  auto trim = [](std::string l) {
    while (!l.empty() && (l.back() == '\r' || l.back() == ' ' || l.back() == '\t')) l.pop_back();
    return l;
  };
  if (!std::getline(in, line) || trim(line) != "ply") fail(1, "expected \"ply\"");
  int n = 1;
  std::vector<PlyElement> elements;
  std::string format;
  bool ended = false;
  while (!ended && std::getline(in, line)) {
    ++n;
    if (n > 10000) fail(n, "no end_header in the first 10000 lines");
    // assimp separates words by spaces and tabs only: "end_header" and a
    // vertical tab never ends its header (an endless loop).
    for (size_t c = 0; c < line.size(); ++c) {
      const unsigned char b = static_cast<unsigned char>(line[c]);
      if ((b < 0x20 && b != '\t' && !(b == '\r' && c + 1 == line.size())) || b == 0x7f) {
        char hex[8];
        std::snprintf(hex, sizeof hex, "0x%02x", b);
        fail(n, std::string("a control character (") + hex + ") in the header");
      }
    }
    std::istringstream words(trim(line));
    std::string key;
    words >> key;
    if (key == "comment" || key == "obj_info") continue;
    if (key == "format") {
      std::string version;
      words >> format >> version;
      if (format != "ascii" && format != "binary_little_endian" && format != "binary_big_endian")
        fail(n, "expected a format of ascii, binary_little_endian or binary_big_endian, got \"" +
                    format + "\"");
      continue;
    }
    if (key == "element") {
      if (!elements.empty() && elements.back().properties.empty())
        fail(n, "element \"" + elements.back().name + "\" has no property");
      PlyElement e;
      long long count = -1;
      if (!(words >> e.name >> count) || count < 0)
        fail(n, "expected \"element NAME COUNT\", got \"" + trim(line) + "\"");
      e.count = uint64_t(count);
      elements.push_back(e);
      continue;
    }
    if (key == "property") {
      if (elements.empty()) fail(n, "a property before any element");
      PlyProperty p;
      std::string type, a, b;
      if (!(words >> type >> a)) fail(n, "expected \"property TYPE NAME\"");
      if (type == "list") {
        if (!(words >> b)) fail(n, "expected \"property list TYPE TYPE NAME\"");
        p.count_type = a;
        p.item_type = b;
        p.count_bytes = plyTypeBytes(a);
        p.item_bytes = plyTypeBytes(b);
        if (!p.count_bytes || !p.item_bytes) fail(n, "unknown type in \"" + trim(line) + "\"");
      } else {
        p.item_type = type;
        p.item_bytes = plyTypeBytes(type);
        if (!p.item_bytes) fail(n, "unknown type \"" + type + "\"");
      }
      elements.back().properties.push_back(p);
      continue;
    }
    if (key == "end_header") {
      if (format.empty()) fail(n, "no format line before end_header");
      if (elements.empty()) fail(n, "no element");
      if (elements.back().properties.empty())
        fail(n, "element \"" + elements.back().name + "\" has no property");
      ended = true;
      continue;
    }
    fail(n, "unknown keyword \"" + key + "\"");
  }
  if (!ended) fail(n, "the header has no end_header");

  // The body, walked against the header: every list's count must be one
  // the rest of the file can hold. assimp sizes a list by its count before
  // reading it (a count of 2^32 took 24 GB: found by fuzz/fuzz_mesh.cpp).
  std::string body((std::istreambuf_iterator<char>(in)), {});
  auto bad = [&](const PlyElement& e, uint64_t item, const std::string& why) {
    throw InputError(path, "not a valid PLY file: element \"" + e.name + "\" " +
                               std::to_string(item) + ": " + why);
  };
  if (format == "ascii") {
    // assimp reads an ASCII body one line per element and sizes a list by
    // its count before it looks for the items (a count of 22...2, wrapped
    // to 32 bits, took 2.3 GB: found by fuzz/fuzz_mesh.cpp). So each line
    // is checked as assimp will read it: numbers only (integers for integer
    // types), every list's count no more than the values left on its line,
    // and exactly the values its element's properties take.
    auto integerType = [](const std::string& t) {
      return t != "float" && t != "float32" && t != "double" && t != "float64";
    };
    auto number = [](const std::string& t, bool integer) {
      size_t c = (t[0] == '+' || t[0] == '-') ? 1 : 0;
      if (c == t.size()) return false;
      if (integer) return t.find_first_not_of("0123456789", c) == std::string::npos;
      if (t.find_first_of("xX") != std::string::npos) return false;
      char* end = nullptr;
      std::strtod(t.c_str(), &end);
      return *end == '\0';
    };
    size_t at = 0, line_no = n;
    auto nextLine = [&](std::vector<std::string>& words) {
      if (at >= body.size()) return false;
      size_t eol = body.find('\n', at);
      if (eol == std::string::npos) eol = body.size();
      std::istringstream line_words(body.substr(at, eol - at));
      at = eol + 1;
      ++line_no;
      words.clear();
      for (std::string w; line_words >> w;) words.push_back(w);
      return true;
    };
    std::vector<std::string> words;
    for (const PlyElement& e : elements)
      for (uint64_t k = 0; k < e.count; ++k) {
        if (!nextLine(words)) bad(e, k, "the file ends before it does");
        const std::string where = "line " + std::to_string(line_no) + ": ";
        if (words.empty()) bad(e, k, where + "an empty line");
        size_t w = 0;
        auto value = [&](const std::string& type) -> const std::string& {
          if (w == words.size()) bad(e, k, where + "fewer values than its properties take");
          if (!number(words[w], integerType(type)))
            bad(e, k,
                where + "\"" + words[w] + "\" is not " +
                    (integerType(type) ? "an integer" : "a number"));
          return words[w++];
        };
        for (const PlyProperty& p : e.properties) {
          if (!p.count_bytes) {
            value(p.item_type);
            continue;
          }
          const std::string& t = value(p.count_type);
          const size_t left = words.size() - w;
          if (t[0] == '-' || t.size() > 19 || std::stoull(t) > left)
            bad(e, k,
                "a list count of \"" + t + "\", more than its line holds (" + where +
                    std::to_string(left) + " values left)");
          for (unsigned long long m = std::stoull(t); m > 0; --m) value(p.item_type);
        }
        if (w != words.size()) bad(e, k, where + "more values than its properties take");
      }
    return;
  }
  const bool big = format == "binary_big_endian";
  uint64_t at = 0;
  for (const PlyElement& e : elements)
    for (uint64_t k = 0; k < e.count; ++k)
      for (const PlyProperty& p : e.properties) {
        if (!p.count_bytes) {
          at += uint64_t(p.item_bytes);
          if (at > body.size()) bad(e, k, "the file ends before it does");
          continue;
        }
        if (at + uint64_t(p.count_bytes) > body.size()) bad(e, k, "the file ends before it does");
        uint64_t items = 0;
        for (int b = 0; b < p.count_bytes; ++b) {
          const uint64_t byte =
              static_cast<unsigned char>(body[at + uint64_t(big ? b : p.count_bytes - 1 - b)]);
          items = (items << 8) | byte;
        }
        // Signed count types: a negative count reads as a huge one here.
        at += uint64_t(p.count_bytes);
        if (items > (body.size() - at) / uint64_t(p.item_bytes))
          bad(e, k, "a list count of " + std::to_string(items) + ", more than the file holds");
        at += items * uint64_t(p.item_bytes);
      }
}

// assimp drops a glTF triangle whose index is past its vertices, which
// then reads as a hole that the repair closes. The indices of every
// primitive of a .gltf file (buffers in files next to it) are checked here
// first, so that the fault is named. Anything this check cannot read is
// left to assimp.
void checkGltfIndices(const std::string& path) {
  nlohmann::json g;
  try {
    std::ifstream in(path, std::ios::binary);
    g = nlohmann::json::parse(in);
  } catch (const std::exception&) {
    return;
  }
  try {
    const auto& accessors = g.at("accessors");
    const auto& views = g.at("bufferViews");
    const auto& buffers = g.at("buffers");
    std::vector<std::string> data(buffers.size());
    const std::filesystem::path dir = std::filesystem::path(path).parent_path();
    const auto& meshes = g.at("meshes");
    for (size_t m = 0; m < meshes.size(); ++m) {
      const auto& prims = meshes[m].at("primitives");
      for (size_t p = 0; p < prims.size(); ++p) {
        if (!prims[p].contains("indices")) continue;
        const auto& idx = accessors.at(prims[p].at("indices").get<size_t>());
        const auto& pos = accessors.at(prims[p].at("attributes").at("POSITION").get<size_t>());
        const size_t vertices = pos.at("count").get<size_t>();
        const auto& view = views.at(idx.at("bufferView").get<size_t>());
        const size_t b = view.at("buffer").get<size_t>();
        const std::string uri = buffers.at(b).at("uri").get<std::string>();
        if (uri.rfind("data:", 0) == 0) continue;
        if (data[b].empty()) {
          std::ifstream bin(dir / uri, std::ios::binary);
          data[b].assign(std::istreambuf_iterator<char>(bin), {});
        }
        const int type = idx.at("componentType").get<int>();
        const size_t size = type == 5121 ? 1 : type == 5123 ? 2 : type == 5125 ? 4 : 0;
        if (size == 0) continue;
        const size_t stride = view.value("byteStride", size);
        const size_t start =
            view.value("byteOffset", size_t(0)) + idx.value("byteOffset", size_t(0));
        const size_t count = idx.at("count").get<size_t>();
        for (size_t k = 0; k < count; ++k) {
          const size_t at = start + k * stride;
          if (at + size > data[b].size()) break;  // a short buffer: assimp says so
          uint32_t v = 0;
          std::memcpy(&v, data[b].data() + at, size);  // little-endian, as glTF is
          if (v >= vertices)
            throw InputError(path, "invalid mesh: primitive " + std::to_string(p) + " of mesh " +
                                       std::to_string(m) + " uses vertex index " +
                                       std::to_string(v) + " (index " + std::to_string(k) +
                                       "), but it has only " + std::to_string(vertices) +
                                       " vertices");
        }
      }
    }
  } catch (const nlohmann::json::exception&) {
    return;  // not the layout this check reads: assimp judges
  }
}

namespace {

using nlohmann::json;

// A glTF 2.0 reference (an index into an array) or a glTF 1.0 one (a key
// into an object); nullptr when it names nothing.
const json* resolve(const json& doc, const char* collection, const json& ref) {
  const auto it = doc.find(collection);
  if (it == doc.end()) return nullptr;
  if (it->is_array() && ref.is_number_unsigned() && ref.get<uint64_t>() < it->size())
    return &(*it)[ref.get<size_t>()];
  if (it->is_object() && ref.is_string()) {
    const auto e = it->find(ref.get<std::string>());
    return e == it->end() ? nullptr : &*e;
  }
  return nullptr;
}

// The bytes a base64 (or percent-encoded) data URI decodes to; -1 when the
// URI is not a data URI.
int64_t dataUriBytes(const std::string& uri) {
  if (uri.rfind("data:", 0) != 0) return -1;
  const size_t comma = uri.find(',');
  if (comma == std::string::npos) return 0;
  const std::string head = uri.substr(0, comma), body = uri.substr(comma + 1);
  if (head.size() >= 7 && head.compare(head.size() - 7, 7, ";base64") == 0) {
    int64_t chars = 0, pad = 0;
    for (char c : body) {
      if (c == '=')
        ++pad;
      else if (!std::isspace(static_cast<unsigned char>(c)))
        ++chars;
    }
    return (chars + pad) / 4 * 3 - std::min<int64_t>(pad, 2);
  }
  int64_t n = 0;
  for (size_t i = 0; i < body.size(); ++i, ++n)
    if (body[i] == '%') i += 2;
  return n;
}

}  // namespace

void checkGltfLayout(const std::string& path) {
  auto fail = [&](const std::string& why) { throw InputError(path, "invalid glTF: " + why); };
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), {});
  // Binary glTF: a 12-byte header, a JSON chunk, then an optional BIN chunk
  // that buffer 0 (without a uri) stands for.
  int64_t bin = -1;
  std::string text = bytes;
  if (bytes.size() >= 4 && bytes.compare(0, 4, "glTF") == 0) {
    auto word = [&](size_t at) {
      uint32_t v = 0;
      if (at + 4 <= bytes.size()) std::memcpy(&v, bytes.data() + at, 4);
      return v;
    };
    if (bytes.size() < 20) fail("binary glTF shorter than its header");
    if (word(4) != 2) fail("binary glTF version " + std::to_string(word(4)) + " (only 2 is read)");
    const uint64_t json_len = word(12);
    if (word(16) != 0x4E4F534Au || 20 + json_len > bytes.size())
      fail("binary glTF without a whole JSON chunk");
    text = bytes.substr(20, json_len);
    const uint64_t next = 20 + ((json_len + 3) & ~uint64_t(3));
    if (next + 8 <= bytes.size() && word(size_t(next) + 4) == 0x004E4942u)
      bin = int64_t(std::min<uint64_t>(word(size_t(next)), bytes.size() - next - 8));
  }
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::exception& e) {
    fail(std::string("not valid JSON (") + e.what() + ")");
  }
  if (!doc.is_object()) fail("the top level is not a JSON object");
  // glTF 1.0 keeps its objects in dictionaries, 2.0 in arrays.
  const json* version =
      doc.contains("asset") && doc["asset"].is_object() && doc["asset"].contains("version")
          ? &doc["asset"]["version"]
          : nullptr;
  const bool version1 = version
                            ? version->is_string() && version->get<std::string>().rfind("1", 0) == 0
                            : doc.contains("accessors") && doc["accessors"].is_object();
  // A non-negative integer field, or its default when absent.
  auto count = [&](const json& o, const char* key, const std::string& what,
                   int64_t dflt) -> int64_t {
    const auto it = o.find(key);
    if (it == o.end()) {
      if (dflt < 0) fail(what + " has no \"" + key + "\"");
      return dflt;
    }
    if (!it->is_number_unsigned() || it->get<uint64_t>() > (uint64_t(1) << 40))
      fail(what + ": \"" + key + "\" is not a byte count or count");
    return it->get<int64_t>();
  };
  auto each = [&](const char* collection, auto&& f) {
    const auto it = doc.find(collection);
    if (it == doc.end()) return;
    if (!it->is_array() && !it->is_object())
      fail(std::string("\"") + collection + "\" is not a list");
    size_t k = 0;
    for (auto e = it->begin(); e != it->end(); ++e, ++k) {
      const std::string name = std::string(collection).substr(0, std::strlen(collection) - 1) +
                               " " + (it->is_array() ? std::to_string(k) : e.key());
      if (!e->is_object()) fail(name + " is not an object");
      f(*e, name);
    }
  };
  // The node hierarchy must be disjoint strict trees (the glTF rule): no
  // node with two parents, no cycle, and a scene's root nodes without a
  // parent. assimp copies a node once for each reference, so a node listed
  // twice by each of n nodes in a chain became 2^n nodes (a chain of 20 in
  // a 1.5 KB file took 3.6 GB and 52 s).
  struct Parent {
    const json* node;
    std::string name;
  };
  std::map<const json*, Parent> parent_of;
  std::map<const json*, std::string> node_name;
  auto listOf = [&](const json& o, const char* key, const std::string& name) {
    const auto it = o.find(key);
    if (it == o.end()) return json::array();
    if (!it->is_array()) fail(name + ": \"" + key + "\" is not a list");
    return *it;
  };
  each("nodes", [&](const json& n, const std::string& name) {
    node_name[&n] = name;
    for (const json& c : listOf(n, "children", name)) {
      const json* child = resolve(doc, "nodes", c);
      if (!child) fail(name + " has a child that does not exist: " + c.dump());
      const auto [it, fresh] = parent_of.emplace(child, Parent{&n, name});
      if (!fresh)
        fail("node " + c.dump() + " is a child of both " + it->second.name + " and " + name +
             " (a node has one parent at most)");
    }
  });
  // With one parent at most, the walk up from a node is a single path: it
  // ends at a root, at a node already known to reach one, or comes back to
  // itself (a cycle). Each node is walked over once.
  std::map<const json*, int> walked;  // 1: on the walk now, 2: reaches a root
  for (const auto& [node, name] : node_name) {
    std::vector<const json*> walk;
    for (const json* at = node; at && walked[at] != 2;) {
      if (walked[at] == 1) fail(node_name[at] + " is its own ancestor (a cycle of nodes)");
      walked[at] = 1;
      walk.push_back(at);
      const auto it = parent_of.find(at);
      at = it == parent_of.end() ? nullptr : it->second.node;
    }
    for (const json* w : walk) walked[w] = 2;
  }
  each("scenes", [&](const json& s, const std::string& name) {
    std::map<const json*, int> listed;
    for (const json& r : listOf(s, "nodes", name)) {
      const json* root = resolve(doc, "nodes", r);
      if (!root) fail(name + " names a node that does not exist: " + r.dump());
      if (const auto it = parent_of.find(root); it != parent_of.end())
        fail(name + " lists " + node_name[root] + " as a root, but it is a child of " +
             it->second.name);
      if (++listed[root] > 1) fail(name + " lists " + node_name[root] + " twice");
    }
  });
  // What each buffer really holds.
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  auto held = [&](const json& buffer, const std::string& name) -> int64_t {
    const auto uri = buffer.find("uri");
    if (uri == buffer.end()) {
      if (bin < 0) fail(name + " has no uri and the file no binary chunk");
      return bin;
    }
    if (!uri->is_string()) fail(name + ": \"uri\" is not a string");
    const std::string u = uri->get<std::string>();
    const int64_t data = dataUriBytes(u);
    if (data >= 0) return data;
    std::error_code ec;
    const auto size = std::filesystem::file_size(dir / u, ec);
    if (ec) fail(name + ": its file \"" + u + "\" cannot be read");
    return int64_t(size);
  };
  each("buffers", [&](const json& b, const std::string& name) {
    const int64_t declared = count(b, "byteLength", name, 0), real = held(b, name);
    if (declared > real)
      fail(name + " declares " + std::to_string(declared) + " bytes, but holds " +
           std::to_string(real));
  });
  // A view's byte range inside its buffer; returns the view's length.
  auto viewBytes = [&](const json& ref, const std::string& who) -> int64_t {
    const json* v = resolve(doc, "bufferViews", ref);
    if (!v || !v->is_object()) fail(who + " names a buffer view that does not exist");
    const json* b = v->contains("buffer") ? resolve(doc, "buffers", v->at("buffer")) : nullptr;
    if (!b || !b->is_object()) fail(who + ": its buffer view names no buffer that exists");
    const int64_t off = count(*v, "byteOffset", who + "'s buffer view", 0);
    const int64_t len = count(*v, "byteLength", who + "'s buffer view", -1);
    if (off + len > held(*b, who + "'s buffer"))
      fail(who + ": its buffer view ends at byte " + std::to_string(off + len) +
           ", past its buffer's " + std::to_string(held(*b, who + "'s buffer")));
    return len;
  };
  each("bufferViews", [&](const json& v, const std::string& name) {
    if (!v.contains("buffer")) fail(name + " has no buffer");
    const json* b = resolve(doc, "buffers", v.at("buffer"));
    if (!b) fail(name + " names a buffer that does not exist");
    const int64_t off = count(v, "byteOffset", name, 0), len = count(v, "byteLength", name, -1);
    if (off + len > held(*b, name + "'s buffer"))
      fail(name + " ends at byte " + std::to_string(off + len) + ", past its buffer's " +
           std::to_string(held(*b, name + "'s buffer")));
    count(v, "byteStride", name, 0);
  });
  auto componentBytes = [&](const json& o, const std::string& who) -> int64_t {
    const auto t = o.find("componentType");
    const int64_t type = t != o.end() && t->is_number_integer() ? t->get<int64_t>() : 0;
    switch (type) {
      case 5120:
      case 5121:
        return 1;
      case 5122:
      case 5123:
        return 2;
      case 5125:
      case 5126:
        return 4;
      default:
        fail(who + ": \"componentType\" is not one of glTF's");
    }
    return 0;
  };
  each("accessors", [&](const json& a, const std::string& name) {
    static const std::pair<const char*, int> kTypes[] = {{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3},
                                                         {"VEC4", 4},   {"MAT2", 4}, {"MAT3", 9},
                                                         {"MAT4", 16}};
    const auto t = a.find("type");
    int components = 0;
    for (const auto& [type, n] : kTypes)
      if (t != a.end() && t->is_string() && *t == type) components = n;
    if (components == 0) fail(name + ": \"type\" is not one of glTF's");
    const int64_t element = components * componentBytes(a, name);
    const int64_t n = count(a, "count", name, -1);
    if (const auto s = a.find("sparse"); s != a.end()) {
      if (!s->is_object() || !s->contains("indices") || !s->contains("values") ||
          !s->at("indices").is_object() || !s->at("values").is_object())
        fail(name + ": \"sparse\" without indices and values");
      const int64_t k = count(*s, "count", name + "'s sparse part", -1);
      const json& idx = s->at("indices");
      const json& val = s->at("values");
      if (!idx.contains("bufferView") || !val.contains("bufferView"))
        fail(name + "'s sparse part has no buffer views");
      const int64_t ib = componentBytes(idx, name + "'s sparse indices");
      if (count(idx, "byteOffset", name, 0) + k * ib > viewBytes(idx.at("bufferView"), name))
        fail(name + "'s sparse indices reach past their buffer view");
      if (count(val, "byteOffset", name, 0) + k * element > viewBytes(val.at("bufferView"), name))
        fail(name + "'s sparse values reach past their buffer view");
    }
    const auto view = a.find("bufferView");
    if (view == a.end()) {
      // glTF 2.0 reads such an accessor as zeros, or from an extension (a
      // Draco-compressed primitive's); assimp's glTF 1.0 reader fails an
      // internal check on it.
      if (version1 && !a.contains("sparse")) fail(name + " has no buffer view (no data)");
      return;
    }
    const int64_t len = viewBytes(*view, name);
    // The stride is the view's in glTF 2.0, the accessor's in glTF 1.0.
    const json* v = resolve(doc, "bufferViews", *view);
    int64_t stride = std::max(count(*v, "byteStride", name + "'s buffer view", 0),
                              count(a, "byteStride", name, 0));
    if (stride == 0) stride = element;
    const int64_t end = count(a, "byteOffset", name, 0) + (n > 0 ? stride * (n - 1) + element : 0);
    if (end > len)
      fail(name + " reaches byte " + std::to_string(end) + " of its buffer view, which has " +
           std::to_string(len));
  });
}

}  // namespace triad
