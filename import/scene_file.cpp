// Reading a scene file: the text, its JSON (with the line and column of a
// syntax error, and keys written twice), then parseScene (scene_loader.cpp).
#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "import/scene_loader.h"
#include "sim/errors.h"

namespace triad {

namespace fs = std::filesystem;

namespace {

// "<file>: line L, column C" of the byte at 0-based `offset`; columns count
// characters (UTF-8 lead bytes), so that they agree with editors.
std::string at(const std::string& file, const std::string& text, std::size_t offset) {
  offset = std::min(offset, text.size());
  const auto line = 1 + std::count(text.begin(), text.begin() + offset, '\n');
  const std::size_t nl = offset == 0 ? std::string::npos : text.rfind('\n', offset - 1);
  std::size_t start = nl == std::string::npos ? 0 : nl + 1;
  if (start == 0 && text.compare(0, 3, "\xEF\xBB\xBF") == 0)
    start = std::min<std::size_t>(3, offset);
  std::size_t column = 1;
  for (std::size_t i = start; i < offset; ++i) {
    if ((static_cast<unsigned char>(text[i]) & 0xC0) != 0x80) ++column;
  }
  return file + ": line " + std::to_string(line) + ", column " + std::to_string(column);
}

// nlohmann's messages start with "[json.exception.parse_error.101] parse
// error at line 3, column 8: "; keep what follows, we give the place.
std::string stripJsonPrefix(std::string msg) {
  if (!msg.empty() && msg[0] == '[') {
    const std::size_t end = msg.find("] ");
    if (end != std::string::npos) msg.erase(0, end + 2);
  }
  if (msg.rfind("parse error", 0) == 0) {
    const std::size_t colon = msg.find(": ");
    if (colon != std::string::npos) msg.erase(0, colon + 2);
  }
  return msg;
}

// nlohmann keeps the last of two equal keys; a scene that says "dx" twice is
// almost certainly a mistake, so the parse callback looks for them.
class DuplicateKeyFinder {
 public:
  bool operator()(int /*depth*/, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using Event = nlohmann::json::parse_event_t;
    switch (event) {
      case Event::object_start:
      case Event::array_start:
        countElement();
        stack_.push_back({event == Event::object_start, {}, {}, -1});
        break;
      case Event::object_end:
      case Event::array_end:
        stack_.pop_back();
        break;
      case Event::key: {
        Level& top = stack_.back();
        top.key = parsed.get<std::string>();
        if (!top.keys.insert(top.key).second && !duplicate_) duplicate_ = path();
        break;
      }
      case Event::value:
        countElement();
        break;
    }
    return true;
  }
  const std::optional<std::string>& duplicate() const { return duplicate_; }

 private:
  struct Level {
    bool is_object;
    std::set<std::string> keys;
    std::string key;  // the key whose value is being read (objects)
    long index;       // the element being read (arrays)
  };
  void countElement() {
    if (!stack_.empty() && !stack_.back().is_object) ++stack_.back().index;
  }
  std::string path() const {
    std::string p;
    for (const Level& l : stack_) {
      if (l.is_object) {
        p += (p.empty() ? "" : ".") + l.key;
      } else {
        p += "[" + std::to_string(l.index) + "]";
      }
    }
    return p;
  }
  std::vector<Level> stack_;
  std::optional<std::string> duplicate_;
};

}  // namespace

SceneDesc loadScene(const std::string& path) {
  // Read the file
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::exists(st)) throw InputError(path, "cannot read the scene file: no such file");
  if (fs::is_directory(st)) throw InputError(path, "expected a scene file, got a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw InputError(path, std::string("cannot read the scene file: ") + std::strerror(errno));
  }
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path, "cannot read the scene file: read error");

  // Parse it as JSON
  DuplicateKeyFinder duplicates;
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text, std::ref(duplicates));
  } catch (const nlohmann::json::parse_error& e) {
    // e.byte is the 1-based offset of the last character read: the culprit.
    std::string what = "invalid JSON: " + stripJsonPrefix(e.what());
    // The reader stops at the token after a forgotten comma, not at the gap.
    const auto has = [&](const char* s) { return what.find(s) != std::string::npos; };
    if ((has("expected '}'") || has("expected ']'")) && !has("unexpected '}'") &&
        !has("unexpected ']'") && !has("end of input")) {
      what += " (is a comma missing before it?)";
    }
    throw InputError(at(path, text, e.byte == 0 ? 0 : e.byte - 1), what);
  } catch (const nlohmann::json::exception& e) {
    // Number overflow ("1e400") carries no offset; find the literal instead.
    const std::string msg = stripJsonPrefix(e.what());
    std::string where = path;
    const std::size_t q0 = msg.find('\''), q1 = msg.rfind('\'');
    if (q0 != std::string::npos && q1 > q0 + 1) {
      const std::size_t pos = text.find(msg.substr(q0 + 1, q1 - q0 - 1));
      if (pos != std::string::npos) where = at(path, text, pos);
    }
    throw InputError(where, "invalid JSON: " + msg);
  }
  if (duplicates.duplicate()) {
    throw InputError(path + ": " + *duplicates.duplicate(),
                     "duplicate key: each key may appear only once in an object (the JSON reader "
                     "would keep only the last)");
  }
  return parseScene(j, path);
}

}  // namespace triad
