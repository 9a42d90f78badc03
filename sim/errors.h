#pragma once
// Errors that cross library boundaries. The command line maps InputError to
// exit status 2 (nothing simulated) and SimulationError to exit status 1.
#include <stdexcept>
#include <string>

namespace triad {

// Invalid user input: a scene, a mesh or a parameter. `where` names the file
// and the key path (for example "scene.json: objects[1].material").
class InputError : public std::runtime_error {
 public:
  InputError(const std::string& where, const std::string& what)
      : std::runtime_error(where.empty() ? what : where + ": " + what), where_(where) {}
  const std::string& where() const { return where_; }

 private:
  std::string where_;
};

// A failure while simulating (an instability, a non-finite value).
class SimulationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace triad
