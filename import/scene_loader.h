#pragma once
// Reading a scene file into a validated SceneDesc. The format is the contract
// in shared/specs/scene-format.md, documented for users (every key, unit,
// default and range) in scenes/README.md.
//
// Validation is strict and complete before anything is simulated: unknown
// keys, wrong types, out-of-range values, dangling material references,
// duplicate names, missing mesh files and shapes outside the domain are all
// InputErrors whose `where` is "<file>: <key path>" (for example
// "scenes/pile.json: objects[1].material") and whose message says what was
// expected and what was found.
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "sim/scene_desc.h"

namespace triad {

// Reads, parses and validates the scene file at `path`. A missing or
// unreadable file, invalid JSON (reported with line and column) and a key
// written twice in one object are InputErrors, as is everything parseScene
// rejects.
SceneDesc loadScene(const std::string& path);

// Validates a parsed scene. `source_path` names the scene in messages and
// anchors relative paths (mesh files, output.dir) at its directory; the
// file itself need not exist, but mesh files must.
SceneDesc parseScene(const nlohmann::json& j, const std::string& source_path);

// The solver settings a run used, every key the scene's `solver` object
// takes under the run's coupling and transfer, defaults included, as they
// are written there: given back as a scene's `solver`, they parse to the
// same settings. run.json records them, so that a run can be repeated
// after a default changed.
nlohmann::ordered_json solverSettings(const SolverDesc& solver);

}  // namespace triad
