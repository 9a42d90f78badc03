#include "import/param_dict.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>

#include "sim/errors.h"

namespace triad {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string inQuotes(const std::string& s) {
  return "\"" + s + "\"";
}

std::string joinQuoted(const std::vector<std::string>& items) {
  std::string out;
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i > 0) out += ", ";
    out += inQuotes(items[i]);
  }
  return out;
}

}  // namespace

std::size_t editDistance(const std::string& a, const std::string& b) {
  // Two rows of the classic dynamic programme suffice.
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t substitute = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, substitute});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::optional<std::string> closestMatch(const std::string& word,
                                        const std::vector<std::string>& candidates) {
  // Allow about one edit in three characters: enough for a slip of the
  // finger, not so much that unrelated keys are offered as fixes. A word
  // that is a clipped form of a candidate ("fov" for "fov_deg") is a match
  // too, however many characters were left off.
  const std::size_t limit = word.size() <= 3 ? 1 : std::max<std::size_t>(2, word.size() / 3);
  std::optional<std::string> best;
  std::size_t best_distance = std::numeric_limits<std::size_t>::max();
  for (const std::string& c : candidates) {
    const std::size_t d = editDistance(word, c);
    const std::string& shorter = word.size() < c.size() ? word : c;
    const std::string& longer = word.size() < c.size() ? c : word;
    const bool clipped = shorter.size() >= 3 && longer.compare(0, shorter.size(), shorter) == 0;
    const bool close = d <= limit && d < std::max(word.size(), c.size());
    if ((close || clipped) && d < best_distance) {
      best = c;
      best_distance = d;
    }
  }
  return best;
}

std::string formatNumber(double v) {
  if (std::isfinite(v) && v == std::trunc(v) && std::fabs(v) < 1e15) {
    return std::to_string(static_cast<long long>(v));
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

std::string describeValue(const nlohmann::json& v) {
  constexpr std::size_t kMaxShown = 60;
  switch (v.type()) {
    case nlohmann::json::value_t::null:
      return "null";
    case nlohmann::json::value_t::boolean:
      return v.get<bool>() ? "true" : "false";
    case nlohmann::json::value_t::string: {
      const auto& s = v.get_ref<const std::string&>();
      if (s.empty()) return "an empty string";
      return "a string (" +
             (s.size() <= kMaxShown ? inQuotes(s) : inQuotes(s.substr(0, kMaxShown)) + "...") + ")";
    }
    case nlohmann::json::value_t::array: {
      if (v.empty()) return "an empty array";
      const std::string dump = v.dump();
      std::string out =
          "an array of " + std::to_string(v.size()) + (v.size() == 1 ? " element" : " elements");
      if (dump.size() <= kMaxShown) out += " (" + dump + ")";
      return out;
    }
    case nlohmann::json::value_t::object:
      return v.empty() ? "an empty object" : "an object";
    default:
      return v.dump();  // numbers, as written
  }
}

// Range

Range Range::any() {
  return Range(-kInf, true, kInf, true);
}
Range Range::positive() {
  return Range(0, true, kInf, true);
}
Range Range::nonNegative() {
  return Range(0, false, kInf, true);
}
Range Range::atLeast(double lo) {
  return Range(lo, false, kInf, true);
}
Range Range::closed(double lo, double hi) {
  return Range(lo, false, hi, false);
}
Range Range::open(double lo, double hi) {
  return Range(lo, true, hi, true);
}
Range Range::closedOpen(double lo, double hi) {
  return Range(lo, false, hi, true);
}
Range Range::openClosed(double lo, double hi) {
  return Range(lo, true, hi, false);
}

bool Range::contains(double v) const {
  const bool above = lo_open_ ? v > lo_ : v >= lo_;
  const bool below = hi_open_ ? v < hi_ : v <= hi_;
  return above && below;
}

std::string Range::describe(const std::string& noun) const {
  const bool vowel = !noun.empty() && std::string("aeiou").find(noun[0]) != std::string::npos;
  const std::string plain = (vowel ? "an " : "a ") + noun;
  const bool lo_bounded = std::isfinite(lo_), hi_bounded = std::isfinite(hi_);
  if (!lo_bounded && !hi_bounded) return plain;
  if (!hi_bounded) {
    if (lo_ == 0) return lo_open_ ? "a positive " + noun : "a non-negative " + noun;
    return plain + (lo_open_ ? " > " : " >= ") + formatNumber(lo_);
  }
  if (!lo_bounded) return plain + (hi_open_ ? " < " : " <= ") + formatNumber(hi_);
  return plain + " in " + (lo_open_ ? "(" : "[") + formatNumber(lo_) + ", " + formatNumber(hi_) +
         (hi_open_ ? ")" : "]");
}

// ParamDict

ParamDict::ParamDict(const nlohmann::json& object, std::string file, std::string path)
    : json_(&object),
      file_(std::move(file)),
      path_(std::move(path)),
      known_(std::make_shared<std::set<std::string>>()) {
  if (!object.is_object()) fail({}, "expected an object, got " + describeValue(object));
}

std::string ParamDict::keyPath(const std::string& key) const {
  if (key.empty()) return path_;
  if (path_.empty()) return key;
  return path_ + "." + key;
}

std::string ParamDict::where(const std::string& key) const {
  const std::string kp = keyPath(key);
  return kp.empty() ? file_ : file_ + ": " + kp;
}

void ParamDict::fail(const std::string& key, const std::string& what) const {
  throw InputError(where(key), what);
}

bool ParamDict::has(const std::string& key) const {
  return find(key) != nullptr;
}

const nlohmann::json* ParamDict::find(const std::string& key) const {
  known_->insert(key);
  auto it = json_->find(key);
  return it == json_->end() ? nullptr : &*it;
}

const nlohmann::json& ParamDict::requireValue(const std::string& key,
                                              const std::string& expected) const {
  if (const nlohmann::json* v = find(key)) return *v;
  // A missing required key is most often a misspelt one: report the key as
  // written, where the user has to make the fix.
  if (auto typo = closestMatch(key, unknownKeys())) {
    fail(*typo, "unknown key " + inQuotes(*typo) + "; did you mean " + inQuotes(key) +
                    "? (a required key: " + expected + ")");
  }
  fail(key, "missing required key; " + expected);
}

std::string ParamDict::listChoices(const std::vector<std::string>& names) {
  return joinQuoted(names);
}

std::size_t ParamDict::choiceIndex(const std::string& key, const nlohmann::json& v,
                                   const std::vector<std::string>& names) const {
  const std::string expected = "expected one of " + listChoices(names);
  if (!v.is_string()) fail(key, expected + ", got " + describeValue(v));
  const auto& s = v.get_ref<const std::string&>();
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == s) return i;
  }
  std::string what = expected + ", got " + inQuotes(s);
  if (auto near = closestMatch(s, names)) what += "; did you mean " + inQuotes(*near) + "?";
  fail(key, what);
}

// Convert and check one value

double ParamDict::toDouble(const std::string& key, const nlohmann::json& v,
                           const Range& range) const {
  const std::string expected = "expected " + range.describe("number");
  if (!v.is_number()) fail(key, expected + ", got " + describeValue(v));
  const double d = v.get<double>();
  if (!std::isfinite(d)) fail(key, expected + ", got a non-finite number");
  if (!range.contains(d)) fail(key, expected + ", got " + v.dump());
  return d;
}

int ParamDict::toInt(const std::string& key, const nlohmann::json& v, const Range& range) const {
  const std::string expected = "expected " + range.describe("integer");
  if (!v.is_number()) fail(key, expected + ", got " + describeValue(v));
  // Writers such as Python's json module may spell 8 as 8.0: accept
  // numbers without a fraction, whatever their JSON type.
  double d = 0;
  if (v.is_number_unsigned()) {
    const auto u = v.get<std::uint64_t>();
    d = u > static_cast<std::uint64_t>(INT_MAX) ? kInf : static_cast<double>(u);
  } else if (v.is_number_integer()) {
    d = static_cast<double>(v.get<std::int64_t>());
  } else {
    d = v.get<double>();
    if (!std::isfinite(d) || d != std::trunc(d)) fail(key, expected + ", got " + v.dump());
  }
  if (d > INT_MAX || d < INT_MIN) fail(key, expected + ", got " + v.dump() + " (out of range)");
  if (!range.contains(d)) fail(key, expected + ", got " + v.dump());
  return static_cast<int>(d);
}

bool ParamDict::toBool(const std::string& key, const nlohmann::json& v) const {
  if (!v.is_boolean()) fail(key, "expected true or false, got " + describeValue(v));
  return v.get<bool>();
}

std::string ParamDict::toString(const std::string& key, const nlohmann::json& v) const {
  if (!v.is_string()) fail(key, "expected a string, got " + describeValue(v));
  const auto& s = v.get_ref<const std::string&>();
  if (s.empty()) fail(key, "expected a non-empty string, got an empty string");
  return s;
}

std::array<double, 3> ParamDict::toVec3(const std::string& key, const nlohmann::json& v) const {
  const std::string expected = "expected an array of 3 numbers";
  if (!v.is_array() || v.size() != 3) fail(key, expected + ", got " + describeValue(v));
  std::array<double, 3> out{};
  for (std::size_t i = 0; i < 3; ++i) {
    if (!v[i].is_number() || !std::isfinite(v[i].get<double>())) {
      fail(key, expected + ", got " + describeValue(v));
    }
    out[i] = v[i].get<double>();
  }
  return out;
}

std::array<int, 2> ParamDict::toIntPair(const std::string& key, const nlohmann::json& v,
                                        const Range& range) const {
  if (!v.is_array() || v.size() != 2) {
    fail(key, "expected an array of 2 integers, got " + describeValue(v));
  }
  // Element errors name the element: "render.resolution[1]".
  return {toInt(key + "[0]", v[0], range), toInt(key + "[1]", v[1], range)};
}

std::vector<ParamDict> ParamDict::toDictArray(const std::string& key, const nlohmann::json& v,
                                              bool allow_empty) const {
  if (!v.is_array()) fail(key, "expected an array of objects, got " + describeValue(v));
  if (v.empty() && !allow_empty) {
    fail(key, "expected a non-empty array of objects, got an empty array");
  }
  std::vector<ParamDict> out;
  out.reserve(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) {
    out.emplace_back(v[i], file_, keyPath(key) + "[" + std::to_string(i) + "]");
  }
  return out;
}

// Typed getters

double ParamDict::requireDouble(const std::string& key, const Range& range) const {
  return toDouble(key, requireValue(key, "expected " + range.describe("number")), range);
}

double ParamDict::getDouble(const std::string& key, double def, const Range& range) const {
  const nlohmann::json* v = find(key);
  return v ? toDouble(key, *v, range) : def;
}

int ParamDict::requireInt(const std::string& key, const Range& range) const {
  return toInt(key, requireValue(key, "expected " + range.describe("integer")), range);
}

int ParamDict::getInt(const std::string& key, int def, const Range& range) const {
  const nlohmann::json* v = find(key);
  return v ? toInt(key, *v, range) : def;
}

bool ParamDict::requireBool(const std::string& key) const {
  return toBool(key, requireValue(key, "expected true or false"));
}

bool ParamDict::getBool(const std::string& key, bool def) const {
  const nlohmann::json* v = find(key);
  return v ? toBool(key, *v) : def;
}

std::string ParamDict::requireString(const std::string& key) const {
  return toString(key, requireValue(key, "expected a string"));
}

std::string ParamDict::getString(const std::string& key, const std::string& def) const {
  const nlohmann::json* v = find(key);
  return v ? toString(key, *v) : def;
}

std::array<double, 3> ParamDict::requireVec3(const std::string& key) const {
  return toVec3(key, requireValue(key, "expected an array of 3 numbers"));
}

std::array<double, 3> ParamDict::getVec3(const std::string& key,
                                         const std::array<double, 3>& def) const {
  const nlohmann::json* v = find(key);
  return v ? toVec3(key, *v) : def;
}

std::array<int, 2> ParamDict::requireIntPair(const std::string& key, const Range& range) const {
  return toIntPair(key, requireValue(key, "expected an array of 2 integers"), range);
}

std::array<int, 2> ParamDict::getIntPair(const std::string& key, const std::array<int, 2>& def,
                                         const Range& range) const {
  const nlohmann::json* v = find(key);
  return v ? toIntPair(key, *v, range) : def;
}

ParamDict ParamDict::requireDict(const std::string& key) const {
  return ParamDict(requireValue(key, "expected an object"), file_, keyPath(key));
}

std::optional<ParamDict> ParamDict::getDict(const std::string& key) const {
  const nlohmann::json* v = find(key);
  if (!v) return std::nullopt;
  return ParamDict(*v, file_, keyPath(key));
}

std::vector<ParamDict> ParamDict::requireDictArray(const std::string& key, bool allow_empty) const {
  const std::string expected =
      allow_empty ? "expected an array of objects" : "expected a non-empty array of objects";
  return toDictArray(key, requireValue(key, expected), allow_empty);
}

std::vector<ParamDict> ParamDict::getDictArray(const std::string& key) const {
  const nlohmann::json* v = find(key);
  return v ? toDictArray(key, *v, true) : std::vector<ParamDict>{};
}

std::vector<std::pair<std::string, ParamDict>> ParamDict::getNamedDicts(
    const std::string& key) const {
  const nlohmann::json* v = find(key);
  if (!v) return {};
  if (!v->is_object()) fail(key, "expected an object of named entries, got " + describeValue(*v));
  std::vector<std::pair<std::string, ParamDict>> out;
  for (auto it = v->begin(); it != v->end(); ++it) {
    if (it.key().empty()) fail(key, "expected non-empty names, got an entry named \"\"");
    out.emplace_back(it.key(), ParamDict(it.value(), file_, keyPath(key) + "." + it.key()));
  }
  return out;
}

// Unknown keys

std::vector<std::string> ParamDict::unknownKeys() const {
  std::vector<std::string> out;
  for (auto it = json_->begin(); it != json_->end(); ++it) {
    if (!known_->count(it.key())) out.push_back(it.key());
  }
  return out;
}

void ParamDict::checkUnknownKeys(const std::string& context,
                                 const std::function<std::string(const std::string&)>& hint) const {
  const std::vector<std::string> unknown = unknownKeys();
  if (unknown.empty()) return;
  const std::string& key = unknown.front();
  std::string what = "unknown key " + inQuotes(key);
  if (!context.empty()) what += " " + context;
  if (hint) {
    const std::string h = hint(key);
    if (!h.empty()) what += " (" + h + ")";
  }
  const std::vector<std::string> known(known_->begin(), known_->end());
  if (auto near = closestMatch(key, known)) {
    what += "; did you mean " + inQuotes(*near) + "?";
  } else {
    what += "; valid keys here: " + (known.empty() ? std::string("none") : joinQuoted(known));
  }
  if (unknown.size() > 1) {
    what += " (also unknown here: " +
            joinQuoted(std::vector<std::string>(unknown.begin() + 1, unknown.end())) + ")";
  }
  fail(key, what);
}

}  // namespace triad
