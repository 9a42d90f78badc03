#pragma once
// A pbrt-v4 style parameter dictionary over one JSON object of a scene file.
// It knows where it sits (the file and the key path, e.g.
// "objects[1].shape.box"), so every error it raises names the exact place;
// it hands out typed, range-checked values; and it records which keys were
// asked for, so that whatever the loader never asked for can be reported as
// an unknown key with the closest valid one. That last part is what keeps a
// typo from silently falling back to a default.
#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace triad {

// Levenshtein distance (insertions, deletions, substitutions; a case change
// is a substitution, so "Density" is one edit from "density").
std::size_t editDistance(const std::string& a, const std::string& b);

// The candidate nearest to `word` if it is close enough to be a plausible
// typo of it; nothing when every candidate is too far to be worth naming.
std::optional<std::string> closestMatch(const std::string& word,
                                        const std::vector<std::string>& candidates);

// A number for messages: integers without a fraction, others in %g style.
std::string formatNumber(double v);

// A short description of a JSON value for "got ..." in messages.
std::string describeValue(const nlohmann::json& v);

// An allowed interval of numbers, open or closed at each end, that can word
// itself for messages ("a positive number", "an integer in [1, 64]").
class Range {
 public:
  static Range any();
  static Range positive();                        // (0, inf)
  static Range nonNegative();                     // [0, inf)
  static Range atLeast(double lo);                // [lo, inf)
  static Range closed(double lo, double hi);      // [lo, hi]
  static Range open(double lo, double hi);        // (lo, hi)
  static Range closedOpen(double lo, double hi);  // [lo, hi)
  static Range openClosed(double lo, double hi);  // (lo, hi]

  bool contains(double v) const;
  // `noun` is "number" or "integer"; the article is chosen to fit.
  std::string describe(const std::string& noun = "number") const;

 private:
  Range(double lo, bool lo_open, double hi, bool hi_open)
      : lo_(lo), hi_(hi), lo_open_(lo_open), hi_open_(hi_open) {}
  double lo_, hi_;
  bool lo_open_, hi_open_;
};

// A view of one JSON object. The JSON must outlive the dictionary and every
// dictionary handed out by it. Copies share the record of keys asked for, so
// a copy may be read and the original checked (or the other way round).
//
// Getters named require* throw when the key is absent; get* return the given
// default. Both throw InputError when the key is present with a wrong type or
// a value out of range. Strings must be non-empty. Every getter, and has(),
// counts the key as known to checkUnknownKeys().
class ParamDict {
 public:
  // `path` is the key path of this object ("" for the top level). Throws
  // unless `object` is a JSON object.
  ParamDict(const nlohmann::json& object, std::string file, std::string path = {});

  const std::string& file() const { return file_; }
  const std::string& path() const { return path_; }
  const nlohmann::json& raw() const { return *json_; }

  // "domain.dx" for key "dx" of the dict at "domain"; the dict's own path
  // for an empty key.
  std::string keyPath(const std::string& key) const;
  // "<file>: <key path>", the `where` of every InputError raised here.
  std::string where(const std::string& key = {}) const;
  // Throws InputError(where(key), what): for checks the loader makes itself.
  [[noreturn]] void fail(const std::string& key, const std::string& what) const;

  bool has(const std::string& key) const;
  // The raw value, or null when absent.
  const nlohmann::json* find(const std::string& key) const;

  // Numbers (any JSON number, finite).
  double requireDouble(const std::string& key, const Range& range = Range::any()) const;
  double getDouble(const std::string& key, double def, const Range& range = Range::any()) const;
  // Integers: JSON integers, or numbers with no fraction (8.0), that fit an int.
  int requireInt(const std::string& key, const Range& range = Range::any()) const;
  int getInt(const std::string& key, int def, const Range& range = Range::any()) const;
  bool requireBool(const std::string& key) const;
  bool getBool(const std::string& key, bool def) const;
  std::string requireString(const std::string& key) const;
  std::string getString(const std::string& key, const std::string& def) const;
  // An array of 3 finite numbers.
  std::array<double, 3> requireVec3(const std::string& key) const;
  std::array<double, 3> getVec3(const std::string& key, const std::array<double, 3>& def) const;
  // An array of 2 integers, each in `range`.
  std::array<int, 2> requireIntPair(const std::string& key,
                                    const Range& range = Range::any()) const;
  std::array<int, 2> getIntPair(const std::string& key, const std::array<int, 2>& def,
                                const Range& range = Range::any()) const;

  // One of a fixed set of strings, mapped to a value. A wrong string is
  // answered with the valid ones and the closest of them.
  template <class E>
  using Choices = std::vector<std::pair<std::string, E>>;
  template <class E>
  E requireEnum(const std::string& key, const Choices<E>& choices) const {
    return choices[choiceIndex(key, requireValue(key, expectedChoice(choices)), names(choices))]
        .second;
  }
  template <class E>
  E getEnum(const std::string& key, E def, const Choices<E>& choices) const {
    const nlohmann::json* v = find(key);
    return v ? choices[choiceIndex(key, *v, names(choices))].second : def;
  }

  // Nested objects.
  ParamDict requireDict(const std::string& key) const;
  std::optional<ParamDict> getDict(const std::string& key) const;
  // An array of objects, each at "key[i]". Absent reads as empty for get*.
  std::vector<ParamDict> requireDictArray(const std::string& key, bool allow_empty = false) const;
  std::vector<ParamDict> getDictArray(const std::string& key) const;
  // An object whose values are all objects, each at "key.name", in the
  // JSON object's key order (sorted by name).
  std::vector<std::pair<std::string, ParamDict>> getNamedDicts(const std::string& key) const;

  // The keys present that no getter (nor has()) has asked for, sorted.
  std::vector<std::string> unknownKeys() const;
  // Throws for the first unknown key: where names the key, what says so,
  // followed by `context` (e.g. "for model \"snow\""), by `hint(key)` when
  // it has something to say (e.g. which model the key belongs to), and by
  // the closest known key or, when none is close, the list of known keys.
  void checkUnknownKeys(const std::string& context = {},
                        const std::function<std::string(const std::string&)>& hint = {}) const;

 private:
  template <class E>
  static std::vector<std::string> names(const Choices<E>& choices) {
    std::vector<std::string> n;
    for (const auto& c : choices) n.push_back(c.first);
    return n;
  }
  template <class E>
  static std::string expectedChoice(const Choices<E>& choices) {
    return "expected one of " + listChoices(names(choices));
  }
  static std::string listChoices(const std::vector<std::string>& names);

  // The value of a required key. When it is absent, throws for a present,
  // unread key that looks like a misspelling of it, or else for the missing
  // key; `expected` says what the key takes.
  const nlohmann::json& requireValue(const std::string& key, const std::string& expected) const;
  std::size_t choiceIndex(const std::string& key, const nlohmann::json& v,
                          const std::vector<std::string>& names) const;
  double toDouble(const std::string& key, const nlohmann::json& v, const Range& range) const;
  int toInt(const std::string& key, const nlohmann::json& v, const Range& range) const;
  bool toBool(const std::string& key, const nlohmann::json& v) const;
  std::string toString(const std::string& key, const nlohmann::json& v) const;
  std::array<double, 3> toVec3(const std::string& key, const nlohmann::json& v) const;
  std::array<int, 2> toIntPair(const std::string& key, const nlohmann::json& v,
                               const Range& range) const;
  std::vector<ParamDict> toDictArray(const std::string& key, const nlohmann::json& v,
                                     bool allow_empty) const;

  const nlohmann::json* json_;
  std::string file_;
  std::string path_;
  std::shared_ptr<std::set<std::string>> known_;
};

}  // namespace triad
