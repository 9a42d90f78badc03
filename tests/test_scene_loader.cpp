// Scene loading: a valid scene comes through as written with defaults filled
// in, and every kind of bad input is an InputError naming the file, the key
// path and what was expected.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <vector>
#include <initializer_list>
#include <string>

#include <nlohmann/json.hpp>

#include "import/param_dict.h"
#include "import/quality.h"
#include "import/scene_loader.h"
#include "sim/errors.h"

namespace triad {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The contract's example (shared/specs/scene-format.md).
json exampleScene() {
  return json::parse(R"({
  "version": 1,
  "name": "sand_on_ramp",
  "frames": { "count": 48, "fps": 24 },
  "domain": {
    "min": [0, 0, 0], "max": [1, 1, 1], "dx": 0.01,
    "boundary": { "type": "slip", "friction": 0.3 }
  },
  "gravity": [0, -9.81, 0],
  "solver": {
    "cfl": 0.4, "max_dt": 0.001, "particles_per_cell": 8,
    "transfer": "apic", "coupling": "three_grid"
  },
  "materials": {
    "sand":  { "model": "drucker_prager", "density": 1600,
               "youngs_modulus": 3.5e5, "poisson_ratio": 0.3,
               "friction_angle_deg": 30, "cohesion": 0 },
    "jelly": { "model": "fixed_corotated", "density": 1000,
               "youngs_modulus": 5e4, "poisson_ratio": 0.3 }
  },
  "objects": [
    { "name": "pile", "kind": "mpm", "material": "sand",
      "shape": { "box": { "min": [0.1, 0.0, 0.1], "max": [0.4, 0.3, 0.4] } },
      "velocity": [0, 0, 0] },
    { "name": "ramp", "kind": "rigid", "density": 2500, "fixed": true,
      "friction": 0.2,
      "shape": { "mesh": { "path": "meshes/ramp.obj", "scale": 1.0,
                 "translate": [0.5, 0.2, 0.5], "rotate_deg": [0, 0, 30] } } },
    { "name": "ball", "kind": "rigid", "density": 500, "friction": 0.3,
      "shape": { "sphere": { "center": [0.5, 0.8, 0.5], "radius": 0.08 } },
      "velocity": [0, -1, 0], "angular_velocity": [0, 0, 0] },
    { "name": "cube", "kind": "elastic", "material": "jelly", "friction": 0.3,
      "shape": { "box": { "min": [0.6, 0.5, 0.6], "max": [0.8, 0.7, 0.8] } } }
  ],
  "output": { "dir": "out/sand_on_ramp", "ply": true, "vdb": true, "png": true },
  "render": {
    "resolution": [640, 360],
    "camera": { "eye": [2.0, 1.2, 2.0], "target": [0.5, 0.3, 0.5], "fov_deg": 40 }
  }
})");
}

// The least a scene must say.
json minimalScene() {
  return json::parse(R"({
  "version": 1, "name": "tiny",
  "domain": { "min": [0, 0, 0], "max": [1, 1, 1], "dx": 0.1 },
  "materials": { "jelly": { "model": "neo_hookean", "density": 1000,
                            "youngs_modulus": 1e4, "poisson_ratio": 0.2 } },
  "objects": [ { "name": "blob", "kind": "mpm", "material": "jelly",
                 "shape": { "sphere": { "center": [0.5, 0.5, 0.5], "radius": 0.2 } } } ]
})");
}

// `j` with the value at JSON pointer `ptr` replaced (or added).
json with(json j, const std::string& ptr, const json& value) {
  j[json::json_pointer(ptr)] = value;
  return j;
}

json without(json j, const std::string& ptr) {
  const json::json_pointer p(ptr);
  j[p.parent_pointer()].erase(p.back());
  return j;
}

::testing::AssertionResult contains(const std::string& message,
                                    std::initializer_list<std::string> parts) {
  for (const std::string& part : parts) {
    if (message.find(part) == std::string::npos) {
      return ::testing::AssertionFailure() << "message: " << message << "\n lacks: " << part;
    }
  }
  return ::testing::AssertionSuccess();
}

// The message of the InputError that parseScene raises for `j`.
std::string parseError(const json& j) {
  try {
    parseScene(j, "virtual.json");
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an InputError";
  return {};
}

class SceneLoaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string test = std::string(info->test_suite_name()) + "_" + info->name();
    std::replace(test.begin(), test.end(), '/', '_');  // parameterised names have slashes
    dir_ = fs::temp_directory_path() / ("triad_scene_" + std::to_string(::getpid()) + "_" + test);
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "meshes");
    std::ofstream(dir_ / "meshes" / "ramp.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  std::string writeText(const std::string& text, const std::string& file = "scene.json") {
    const fs::path path = dir_ / file;
    std::ofstream(path, std::ios::binary) << text;
    return path.string();
  }
  SceneDesc load(const json& j) { return loadScene(writeText(j.dump(2))); }

  // The message of the InputError that loading the file raises.
  std::string errorOfFile(const std::string& path) {
    try {
      loadScene(path);
    } catch (const InputError& e) {
      return e.what();
    }
    ADD_FAILURE() << "expected an InputError from " << path;
    return {};
  }
  std::string error(const json& j) { return errorOfFile(writeText(j.dump(2))); }

  fs::path dir_;
};

// Valid scenes

TEST_F(SceneLoaderTest, ParsesTheContractExampleAsWritten) {
  const SceneDesc s = load(exampleScene());
  EXPECT_EQ(s.source_path, (dir_ / "scene.json").string());
  EXPECT_EQ(s.version, 1);
  EXPECT_EQ(s.name, "sand_on_ramp");
  EXPECT_EQ(s.frames.count, 48);
  EXPECT_EQ(s.frames.fps, 24.0);
  EXPECT_EQ(s.domain.min, (Vec3Desc{0, 0, 0}));
  EXPECT_EQ(s.domain.max, (Vec3Desc{1, 1, 1}));
  EXPECT_EQ(s.domain.dx, 0.01);
  EXPECT_EQ(s.domain.boundary.type, BoundaryType::Slip);
  EXPECT_EQ(s.domain.boundary.friction, 0.3);
  EXPECT_EQ(s.gravity, (Vec3Desc{0, -9.81, 0}));
  EXPECT_EQ(s.solver.cfl, 0.4);
  EXPECT_EQ(s.solver.max_dt, 0.001);
  EXPECT_EQ(s.solver.particles_per_cell, 8);
  EXPECT_EQ(s.solver.transfer, TransferScheme::Apic);
  EXPECT_EQ(s.solver.coupling, CouplingScheme::ThreeGrid);

  // Materials come in name order; objects refer to them by index.
  ASSERT_EQ(s.materials.size(), 2u);
  const MaterialDesc& jelly = s.materials[0];
  const MaterialDesc& sand = s.materials[1];
  EXPECT_EQ(jelly.name, "jelly");
  EXPECT_EQ(jelly.model, MaterialModel::FixedCorotated);
  EXPECT_EQ(jelly.density, 1000.0);
  EXPECT_EQ(jelly.youngs_modulus, 5e4);
  EXPECT_EQ(jelly.poisson_ratio, 0.3);
  EXPECT_EQ(sand.name, "sand");
  EXPECT_EQ(sand.model, MaterialModel::DruckerPrager);
  EXPECT_EQ(sand.density, 1600.0);
  EXPECT_EQ(sand.youngs_modulus, 3.5e5);
  EXPECT_EQ(sand.poisson_ratio, 0.3);
  EXPECT_EQ(sand.friction_angle_deg, 30.0);
  EXPECT_EQ(sand.cohesion, 0.0);

  ASSERT_EQ(s.objects.size(), 4u);
  const ObjectDesc& pile = s.objects[0];
  EXPECT_EQ(pile.name, "pile");
  EXPECT_EQ(pile.kind, ObjectKind::Mpm);
  EXPECT_EQ(pile.material, 1);
  const auto& box = std::get<BoxDesc>(pile.shape);
  EXPECT_EQ(box.min, (Vec3Desc{0.1, 0.0, 0.1}));
  EXPECT_EQ(box.max, (Vec3Desc{0.4, 0.3, 0.4}));
  EXPECT_EQ(pile.velocity, (Vec3Desc{0, 0, 0}));

  const ObjectDesc& ramp = s.objects[1];
  EXPECT_EQ(ramp.name, "ramp");
  EXPECT_EQ(ramp.kind, ObjectKind::Rigid);
  EXPECT_EQ(ramp.material, -1);
  EXPECT_EQ(ramp.density, 2500.0);
  EXPECT_TRUE(ramp.fixed);
  EXPECT_EQ(ramp.friction, 0.2);
  const auto& mesh = std::get<MeshDesc>(ramp.shape);
  EXPECT_EQ(mesh.path, "meshes/ramp.obj");
  EXPECT_EQ(fs::path(mesh.resolved_path), (dir_ / "meshes" / "ramp.obj").lexically_normal());
  EXPECT_EQ(mesh.scale, 1.0);
  EXPECT_EQ(mesh.translate, (Vec3Desc{0.5, 0.2, 0.5}));
  EXPECT_EQ(mesh.rotate_deg, (Vec3Desc{0, 0, 30}));

  const ObjectDesc& ball = s.objects[2];
  EXPECT_EQ(ball.kind, ObjectKind::Rigid);
  EXPECT_FALSE(ball.fixed);
  EXPECT_EQ(ball.density, 500.0);
  EXPECT_EQ(ball.friction, 0.3);
  EXPECT_EQ(ball.velocity, (Vec3Desc{0, -1, 0}));
  EXPECT_EQ(ball.angular_velocity, (Vec3Desc{0, 0, 0}));
  const auto& sphere = std::get<SphereDesc>(ball.shape);
  EXPECT_EQ(sphere.center, (Vec3Desc{0.5, 0.8, 0.5}));
  EXPECT_EQ(sphere.radius, 0.08);

  const ObjectDesc& cube = s.objects[3];
  EXPECT_EQ(cube.kind, ObjectKind::Elastic);
  EXPECT_EQ(cube.material, 0);
  EXPECT_EQ(cube.friction, 0.3);
  EXPECT_TRUE(std::holds_alternative<BoxDesc>(cube.shape));

  // output.dir is relative to the scene file.
  EXPECT_EQ(fs::path(s.output.dir), (dir_ / "out" / "sand_on_ramp").lexically_normal());
  EXPECT_TRUE(s.output.ply && s.output.vdb && s.output.png);
  EXPECT_EQ(s.render.resolution, (std::array<int, 2>{640, 360}));
  ASSERT_TRUE(s.render.camera.has_value());
  EXPECT_EQ(s.render.camera->eye, (Vec3Desc{2.0, 1.2, 2.0}));
  EXPECT_EQ(s.render.camera->target, (Vec3Desc{0.5, 0.3, 0.5}));
  EXPECT_EQ(s.render.camera->fov_deg, 40.0);
}

TEST_F(SceneLoaderTest, FillsDefaultsForWhatIsLeftOut) {
  const SceneDesc s = load(minimalScene());
  const SceneDesc defaults;
  EXPECT_EQ(s.frames.count, defaults.frames.count);
  EXPECT_EQ(s.frames.fps, defaults.frames.fps);
  EXPECT_EQ(s.domain.boundary.type, BoundaryType::Slip);
  EXPECT_EQ(s.domain.boundary.friction, 0.0);
  EXPECT_EQ(s.gravity, (Vec3Desc{0, -9.81, 0}));
  EXPECT_EQ(s.solver.cfl, defaults.solver.cfl);
  EXPECT_EQ(s.solver.max_dt, defaults.solver.max_dt);
  EXPECT_EQ(s.solver.particles_per_cell, defaults.solver.particles_per_cell);
  EXPECT_EQ(s.solver.transfer, TransferScheme::Apic);
  EXPECT_EQ(s.solver.flip_ratio, defaults.solver.flip_ratio);
  EXPECT_EQ(s.solver.coupling, CouplingScheme::ThreeGrid);
  // The default output directory is relative to the working directory.
  EXPECT_EQ(fs::path(s.output.dir), fs::path("out") / "tiny");
  EXPECT_TRUE(s.output.ply && s.output.vdb && s.output.png);
  EXPECT_EQ(s.render.resolution, (std::array<int, 2>{640, 360}));
  EXPECT_FALSE(s.render.camera.has_value());
  EXPECT_EQ(s.objects[0].velocity, (Vec3Desc{0, 0, 0}));
}

TEST_F(SceneLoaderTest, ReadsSleepAsAFlagOrItsSettings) {
  json j = minimalScene();
  EXPECT_FALSE(load(j).solver.sleep.enabled);
  j["solver"] = {{"sleep", true}};
  const SleepDesc defaults;
  EXPECT_TRUE(load(j).solver.sleep.enabled);
  EXPECT_EQ(load(j).solver.sleep.speed, defaults.speed);
  j["solver"] = {{"sleep", {{"speed", 0.002}, {"delay", 0.5}}}};
  const SleepDesc s = load(j).solver.sleep;
  EXPECT_TRUE(s.enabled);
  EXPECT_EQ(s.speed, 0.002);
  EXPECT_EQ(s.delay, 0.5);
  EXPECT_TRUE(s.neighbours);
  j["solver"] = {{"sleep", {{"neighbours", false}}}};
  EXPECT_FALSE(load(j).solver.sleep.neighbours);
  j["solver"] = {{"sleep", {{"neighbours", 1}}}};
  EXPECT_TRUE(contains(parseError(j), {"solver.sleep.neighbours"}));
  j["solver"] = {{"sleep", {{"speed", -1}}}};
  EXPECT_TRUE(contains(parseError(j), {"virtual.json", "solver.sleep.speed"}));
  j["solver"] = {{"sleep", {{"sped", 0.1}}}};
  EXPECT_TRUE(contains(parseError(j), {"solver.sleep.sped", "speed"}));
  j["solver"] = {{"sleep", "yes"}};
  EXPECT_TRUE(contains(parseError(j), {"solver.sleep"}));
}

TEST_F(SceneLoaderTest, FillsModelDefaultsAndReadsExtensions) {
  json j = minimalScene();
  j["materials"]["snow"] = {
      {"model", "snow"}, {"density", 400}, {"youngs_modulus", 1.4e5}, {"poisson_ratio", 0.2}};
  j["materials"]["water"] = {
      {"model", "water"}, {"density", 1000}, {"bulk_modulus", 2e5}, {"gamma", 1}};
  j["materials"]["sand"] = {{"model", "drucker_prager"},
                            {"density", 1600},
                            {"youngs_modulus", 3.5e5},
                            {"poisson_ratio", 0.3}};
  j["solver"] = {{"transfer", "flip"}, {"flip_ratio", 0.5}, {"coupling", "single_grid"}};
  j["objects"][0]["material"] = "water";
  const SceneDesc s = load(j);
  const MaterialDesc defaults;
  ASSERT_EQ(s.materials.size(), 4u);  // jelly, sand, snow, water
  const MaterialDesc& sand = s.materials[1];
  EXPECT_EQ(sand.friction_angle_deg, defaults.friction_angle_deg);
  EXPECT_EQ(sand.cohesion, defaults.cohesion);
  const MaterialDesc& snow = s.materials[2];
  EXPECT_EQ(snow.model, MaterialModel::Snow);
  EXPECT_EQ(snow.critical_compression, defaults.critical_compression);
  EXPECT_EQ(snow.critical_stretch, defaults.critical_stretch);
  EXPECT_EQ(snow.hardening, defaults.hardening);
  const MaterialDesc& water = s.materials[3];
  EXPECT_EQ(water.model, MaterialModel::Water);
  EXPECT_EQ(water.bulk_modulus, 2e5);
  EXPECT_EQ(water.viscosity, 0.0);
  EXPECT_EQ(water.gamma, 1.0);
  EXPECT_EQ(s.objects[0].material, 3);
  EXPECT_EQ(s.solver.transfer, TransferScheme::Flip);
  EXPECT_EQ(s.solver.flip_ratio, 0.5);
  EXPECT_EQ(s.solver.coupling, CouplingScheme::SingleGrid);
}

// The cells of a markdown table row ("| a | b |"), trimmed; none for
// another line.
std::vector<std::string> tableCells(const std::string& line) {
  std::vector<std::string> cells;
  if (line.rfind("|", 0) != 0) return cells;
  for (size_t at = 1, next; (next = line.find('|', at)) != std::string::npos; at = next + 1) {
    std::string c = line.substr(at, next - at);
    c.erase(0, c.find_first_not_of(' '));
    c.erase(c.find_last_not_of(' ') + 1);
    cells.push_back(c);
  }
  return cells;
}

// A cell that is a literal in backticks, and what is inside them.
bool quoted(const std::string& t) { return t.size() >= 2 && t.front() == '`' && t.back() == '`'; }
std::string unquoted(const std::string& t) { return t.substr(1, t.size() - 2); }

// The defaults scenes/README.md documents, by section ("## `solver`"; the
// rows before the first such heading are "Top level"): a table row whose
// key is in backticks and whose third column is a JSON literal in backticks.
std::map<std::string, std::map<std::string, json>> documentedDefaults() {
  std::ifstream in(std::string(TRIAD_SOURCE_DIR) + "/scenes/README.md");
  std::map<std::string, std::map<std::string, json>> doc;
  std::string line, section = "Top level";
  while (std::getline(in, line)) {
    if (line.rfind("## `", 0) == 0) {
      section = line.substr(4, line.find('`', 4) - 4);
      continue;
    }
    const std::vector<std::string> cells = tableCells(line);
    if (cells.size() < 4 || !quoted(cells[0]) || !quoted(cells[2])) continue;
    const json value = json::parse(unquoted(cells[2]), nullptr, false);
    if (!value.is_discarded()) doc[section][unquoted(cells[0])] = value;
  }
  return doc;
}

// What the reference says is what the loader does: for every default it
// documents, a scene without the key and one with the documented value read
// the same. The old defaults test compared the loader with its own structs,
// so a default changed in the code (and the struct) passed with the README
// saying otherwise.
TEST_F(SceneLoaderTest, DefaultsAreTheDocumentedOnes) {
  const auto doc = documentedDefaults();
  json base = minimalScene();
  base["materials"]["snow"] = {
      {"model", "snow"}, {"density", 400}, {"youngs_modulus", 1.4e5}, {"poisson_ratio", 0.2}};
  base["materials"]["sand"] = {
      {"model", "drucker_prager"}, {"density", 1600}, {"youngs_modulus", 3.5e5},
      {"poisson_ratio", 0.3}};
  base["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 2e5}};
  using Get = std::function<json(const SceneDesc&)>;
  struct Case {
    std::string section, key, pointer;
    Get get;
  };
  const std::vector<Case> cases = {
      {"Top level", "gravity", "/gravity", [](const SceneDesc& s) { return json(s.gravity); }},
      {"frames", "count", "/frames/count", [](const SceneDesc& s) { return json(s.frames.count); }},
      {"frames", "fps", "/frames/fps", [](const SceneDesc& s) { return json(s.frames.fps); }},
      {"domain", "type", "/domain/boundary/type",
       [](const SceneDesc& s) { return json(int(s.domain.boundary.type)); }},
      {"domain", "friction", "/domain/boundary/friction",
       [](const SceneDesc& s) { return json(s.domain.boundary.friction); }},
      {"solver", "cfl", "/solver/cfl", [](const SceneDesc& s) { return json(s.solver.cfl); }},
      {"solver", "max_dt", "/solver/max_dt",
       [](const SceneDesc& s) { return json(s.solver.max_dt); }},
      {"solver", "particles_per_cell", "/solver/particles_per_cell",
       [](const SceneDesc& s) { return json(s.solver.particles_per_cell); }},
      {"solver", "transfer", "/solver/transfer",
       [](const SceneDesc& s) { return json(int(s.solver.transfer)); }},
      {"solver", "coupling", "/solver/coupling",
       [](const SceneDesc& s) { return json(int(s.solver.coupling)); }},
      {"solver", "contact_velocity", "/solver/contact_velocity",
       [](const SceneDesc& s) { return json(int(s.solver.contact_velocity)); }},
      {"solver", "solid_readback", "/solver/solid_readback",
       [](const SceneDesc& s) { return json(int(s.solver.solid_readback)); }},
      {"solver", "rigid_node_mass", "/solver/rigid_node_mass",
       [](const SceneDesc& s) { return json(int(s.solver.rigid_node_mass)); }},
      {"solver", "rigid_node_velocity", "/solver/rigid_node_velocity",
       [](const SceneDesc& s) { return json(int(s.solver.rigid_node_velocity)); }},
      {"solver", "contact_reach", "/solver/contact_reach",
       [](const SceneDesc& s) { return json(s.solver.contact_reach); }},
      {"solver", "front_fields", "/solver/front_fields",
       [](const SceneDesc& s) { return json(s.solver.front_fields); }},
      {"solver", "front_angle_deg", "/solver/front_angle_deg",
       [](const SceneDesc& s) { return json(s.solver.front_angle_deg); }},
      {"solver", "contact_normal", "/solver/contact_normal",
       [](const SceneDesc& s) { return json(int(s.solver.contact_normal)); }},
      {"solver", "rigid_collision", "/solver/rigid_collision",
       [](const SceneDesc& s) { return json(int(s.solver.rigid_collision)); }},
      {"solver", "contact_gap", "/solver/contact_gap",
       [](const SceneDesc& s) { return json(s.solver.contact_gap); }},
      {"solver", "contact_gap_fixed", "/solver/contact_gap_fixed",
       [](const SceneDesc& s) { return json(s.solver.contact_gap_fixed); }},
      {"solver", "coupling_iterations", "/solver/coupling_iterations",
       [](const SceneDesc& s) { return json(s.solver.coupling_iterations); }},
      {"solver", "elastic_contact_passes", "/solver/elastic_contact_passes",
       [](const SceneDesc& s) { return json(s.solver.elastic_contact_passes); }},
      {"solver", "contact_iterations", "/solver/contact_iterations",
       [](const SceneDesc& s) { return json(s.solver.contact_iterations); }},
      {"materials", "critical_compression", "/materials/snow/critical_compression",
       [](const SceneDesc& s) { return json(s.materials[2].critical_compression); }},
      {"materials", "critical_stretch", "/materials/snow/critical_stretch",
       [](const SceneDesc& s) { return json(s.materials[2].critical_stretch); }},
      {"materials", "hardening", "/materials/snow/hardening",
       [](const SceneDesc& s) { return json(s.materials[2].hardening); }},
      {"materials", "friction_angle_deg", "/materials/sand/friction_angle_deg",
       [](const SceneDesc& s) { return json(s.materials[1].friction_angle_deg); }},
      {"materials", "cohesion", "/materials/sand/cohesion",
       [](const SceneDesc& s) { return json(s.materials[1].cohesion); }},
      {"materials", "viscosity", "/materials/water/viscosity",
       [](const SceneDesc& s) { return json(s.materials[3].viscosity); }},
      {"materials", "gamma", "/materials/water/gamma",
       [](const SceneDesc& s) { return json(s.materials[3].gamma); }},
      {"output", "ply", "/output/ply", [](const SceneDesc& s) { return json(s.output.ply); }},
      {"output", "vdb", "/output/vdb", [](const SceneDesc& s) { return json(s.output.vdb); }},
      {"output", "png", "/output/png", [](const SceneDesc& s) { return json(s.output.png); }},
      {"output", "vdb_surface", "/output/vdb_surface",
       [](const SceneDesc& s) { return json(s.output.vdb_surface); }},
      {"output", "surface_mesh", "/output/surface_mesh",
       [](const SceneDesc& s) { return json(s.output.surface_mesh); }},
      {"output", "surface_smoothing", "/output/surface_smoothing",
       [](const SceneDesc& s) { return json(s.output.surface_smoothing); }},
      {"output", "surface_adaptivity", "/output/surface_adaptivity",
       [](const SceneDesc& s) { return json(s.output.surface_adaptivity); }},
      {"output", "vtk", "/output/vtk", [](const SceneDesc& s) { return json(s.output.vtk); }},
      {"output", "checkpoints", "/output/checkpoints",
       [](const SceneDesc& s) { return json(s.output.checkpoints); }},
      {"render", "resolution", "/render/resolution",
       [](const SceneDesc& s) { return json(s.render.resolution); }},
      {"render", "style", "/render/style",
       [](const SceneDesc& s) { return json(int(s.render.style)); }},
      {"render", "legend", "/render/legend",
       [](const SceneDesc& s) { return json(s.render.legend); }},
  };
  const SceneDesc without = load(base);
  for (const Case& c : cases) {
    const auto sec = doc.find(c.section);
    ASSERT_NE(sec, doc.end()) << "scenes/README.md has no section " << c.section;
    const auto it = sec->second.find(c.key);
    ASSERT_NE(it, sec->second.end())
        << "scenes/README.md documents no default for " << c.section << " / " << c.key;
    const SceneDesc with_doc = load(with(base, c.pointer, it->second));
    EXPECT_EQ(c.get(without), c.get(with_doc))
        << c.pointer << ": the loader's default is not the documented " << it->second.dump();
  }
  // flip_ratio is allowed only with transfer flip.
  const json flip = with(base, "/solver/transfer", "flip");
  const json documented = doc.at("solver").at("flip_ratio");
  EXPECT_EQ(load(flip).solver.flip_ratio,
            load(with(flip, "/solver/flip_ratio", documented)).solver.flip_ratio);
}

// What run.json records as the solver's settings: every key with its
// value, defaults included, which parses back to the same settings.
TEST_F(SceneLoaderTest, SolverSettingsParseBackToTheSameSettings) {
  const std::vector<json> solvers = {
      json::object(),
      {{"cfl", 0.3},
       {"max_dt", 5e-4},
       {"particles_per_cell", 27},
       {"transfer", "flip"},
       {"flip_ratio", 0.9},
       {"coupling", "three_grid"},
       {"contact_reach", 0.75},
       {"contact_normal", "samples"},
       {"rigid_collision", "jacobi"},
       {"contact_gap", false},
       {"contact_gap_fixed", false},
       {"front_fields", false},
       {"elastic_contact_passes", 3},
       {"front_angle_deg", 30.0},
       {"contact_velocity", "before_update"},
       {"solid_readback", "combined"},
       {"rigid_node_mass", "body_share"},
       {"rigid_node_velocity", "samples"},
       {"coupling_iterations", 300},
       {"contact_iterations", 5},
       {"sleep", false}},
      {{"transfer", "pic"}, {"coupling", "single_grid"}},
      {{"front_fields", true}, {"sleep", {{"speed", 0.02}, {"delay", 0.5}, {"neighbours", false}}}},
      // The three-grid switches unlike each other: one written from
      // another's field reads back wrong.
      {{"contact_gap", false}, {"contact_gap_fixed", true}, {"front_fields", true}},
  };
  for (const json& solver : solvers) {
    const json settings = solverSettings(load(with(minimalScene(), "/solver", solver)).solver);
    // What the scene said is there as it said it.
    for (const auto& [key, value] : solver.items())
      EXPECT_EQ(settings.at(key), value) << key << " in " << solver.dump();
    // And all of it, given back as a scene's solver, reads the same.
    const json again = solverSettings(load(with(minimalScene(), "/solver", settings)).solver);
    EXPECT_EQ(again, settings) << solver.dump();
  }
  // The defaults are spelled out, the keys of one coupling or transfer
  // only with it.
  const json defaults = solverSettings(load(minimalScene()).solver);
  EXPECT_EQ(defaults.at("contact_gap_fixed"), true);
  EXPECT_EQ(defaults.at("sleep"), false);
  EXPECT_FALSE(defaults.contains("flip_ratio"));
  const json single =
      solverSettings(load(with(minimalScene(), "/solver/coupling", "single_grid")).solver);
  EXPECT_FALSE(single.contains("contact_reach"));
  EXPECT_FALSE(single.contains("elastic_contact_passes"));
  EXPECT_EQ(defaults.at("elastic_contact_passes"), 8);
  EXPECT_EQ(defaults.size(), single.size() + 8);
}

// Surface meshes are files named after materials: names that cannot name a
// file, or that clash on file systems ignoring case, are refused then (and
// only then); the meshing keys are range-checked.
TEST_F(SceneLoaderTest, SurfaceMeshNamesAndSettings) {
  json j = minimalScene();
  j["materials"]["wet sand"] = j["materials"].begin().value();
  EXPECT_NO_THROW(load(j));
  j["output"] = {{"surface_mesh", true}};
  EXPECT_TRUE(contains(error(j), {"materials.wet sand", "surfaces/NAME.FFFF.ply", "\"wet sand\""}));
  json clash = minimalScene();
  const json m = clash["materials"].begin().value();
  clash["materials"]["Water"] = m;
  clash["materials"]["water"] = m;
  clash["output"] = {{"surface_mesh", true}};
  EXPECT_TRUE(contains(error(clash), {"other than in case", "\"Water\""}));
  json k = minimalScene();
  k["output"] = {{"surface_mesh", true}, {"surface_smoothing", 21}};
  EXPECT_TRUE(contains(error(k), {"output.surface_smoothing", "[0, 20]"}));
  k["output"] = {{"surface_mesh", true}, {"surface_adaptivity", 1.5}};
  EXPECT_TRUE(contains(error(k), {"output.surface_adaptivity", "[0, 1]"}));
  k["output"] = {{"vtk", "yes"}};
  EXPECT_TRUE(contains(error(k), {"output.vtk"}));
}

// The quality presets are the ones scenes/README.md's table documents: dx
// "2 ×", "as written" or "½ ×" the scene's, particles per cell, cfl,
// transfer and the previews' supersampling, for every preset the code has
// and no other.
TEST(QualityDocs, PresetsAreTheDocumentedOnes) {
  std::ifstream in(std::string(TRIAD_SOURCE_DIR) + "/scenes/README.md");
  std::string line;
  size_t rows = 0;
  while (std::getline(in, line)) {
    const std::vector<std::string> cells = tableCells(line);
    if (cells.size() != 6 || !quoted(cells[0])) continue;
    const std::string name = unquoted(cells[0]);
    const auto p = findQualityPreset(name);
    if (!p && name != "draft" && name != "preview" && name != "final") continue;
    ASSERT_TRUE(p.has_value()) << "documented preset " << name << " is not in the code";
    ++rows;
    const double factor = cells[1].rfind("2 ×", 0) == 0    ? 2.0
                          : cells[1].rfind("½ ×", 0) == 0  ? 0.5
                          : cells[1] == "as written"       ? 1.0
                                                           : -1.0;
    EXPECT_EQ(p->dx_factor, factor) << name << ": documented " << cells[1];
    EXPECT_EQ(p->particles_per_cell, std::stoi(cells[2])) << name;
    EXPECT_EQ(p->cfl, std::stod(cells[3])) << name;
    EXPECT_EQ("`" + transferName(p->transfer) + "`", cells[4]) << name;
    EXPECT_EQ(p->preview_supersample, std::stoi(cells[5])) << name;
  }
  EXPECT_EQ(rows, qualityPresets().size()) << "every preset documented, once";
}

TEST_F(SceneLoaderTest, AcceptsIntegersWrittenWithAZeroFraction) {
  const SceneDesc s = load(with(exampleScene(), "/solver/particles_per_cell", 8.0));
  EXPECT_EQ(s.solver.particles_per_cell, 8);
}

TEST_F(SceneLoaderTest, KeepsAbsolutePaths) {
  const std::string mesh = (dir_ / "meshes" / "ramp.obj").string();
  const std::string out = (dir_ / "elsewhere").string();
  json j = with(exampleScene(), "/objects/1/shape/mesh/path", mesh);
  const SceneDesc s = load(with(j, "/output/dir", out));
  EXPECT_EQ(std::get<MeshDesc>(s.objects[1].shape).resolved_path, mesh);
  EXPECT_EQ(s.output.dir, out);
}

TEST_F(SceneLoaderTest, ParseSceneResolvesPathsAgainstTheNamedFile) {
  const SceneDesc s = parseScene(exampleScene(), (dir_ / "virtual.json").string());
  EXPECT_EQ(fs::path(std::get<MeshDesc>(s.objects[1].shape).resolved_path),
            (dir_ / "meshes" / "ramp.obj").lexically_normal());
}

// Reading the file

TEST_F(SceneLoaderTest, MissingFileIsAnInputError) {
  const std::string path = (dir_ / "no_such_scene.json").string();
  const std::string msg = errorOfFile(path);
  EXPECT_TRUE(contains(msg, {path, "no such file"}));
  EXPECT_TRUE(contains(errorOfFile(dir_.string()), {"directory"}));
}

TEST_F(SceneLoaderTest, JsonSyntaxErrorReportsLineAndColumn) {
  const std::string path = writeText("{\n  \"version\": 1,\n  \"name\": x\n}\n", "broken.json");
  EXPECT_TRUE(contains(errorOfFile(path), {"broken.json", "line 3, column 11", "invalid JSON"}));

  // Columns count characters, not bytes (the é is two bytes).
  const std::string utf8 = writeText("{\n  \"name\": \"\xC3\xA9\" x\n}\n", "utf8.json");
  EXPECT_TRUE(contains(errorOfFile(utf8), {"line 2, column 15"}));

  const std::string trailing = writeText("{\n  \"version\": 1,\n}\n", "trailing.json");
  EXPECT_TRUE(contains(errorOfFile(trailing), {"line 3, column 1"}));

  const std::string empty = writeText("", "empty.json");
  EXPECT_TRUE(contains(errorOfFile(empty), {"empty.json", "line 1, column 1"}));

  const std::string huge = writeText("{\n \"version\": 1e400 }", "huge.json");
  EXPECT_TRUE(contains(errorOfFile(huge), {"huge.json", "line 2, column 13", "overflow"}));
}

TEST_F(SceneLoaderTest, KeyWrittenTwiceIsAnError) {
  std::string text = exampleScene().dump(2);
  text.replace(text.find("\"dx\""), 4, "\"dx\": 0.02, \"dx\"");
  EXPECT_TRUE(contains(errorOfFile(writeText(text)), {"scene.json: domain.dx", "duplicate key"}));

  text = exampleScene().dump(2);
  text.replace(text.find("\"radius\""), 8, "\"radius\": 1, \"radius\"");
  EXPECT_TRUE(contains(errorOfFile(writeText(text)), {"objects[2].shape.sphere.radius"}));
}

TEST_F(SceneLoaderTest, TopLevelMustBeAnObject) {
  EXPECT_TRUE(contains(errorOfFile(writeText("[1, 2]")), {"scene.json", "expected an object"}));
  EXPECT_TRUE(contains(parseError(json(3)), {"virtual.json", "expected an object, got 3"}));
}

// Unknown keys and typos

TEST_F(SceneLoaderTest, MisspeltRequiredKeyIsNamedWithTheFix) {
  json j = exampleScene();
  j["materials"]["sand"]["youngs_modulu"] = j["materials"]["sand"]["youngs_modulus"];
  const std::string msg = error(without(j, "/materials/sand/youngs_modulus"));
  EXPECT_TRUE(contains(msg, {"scene.json: materials.sand.youngs_modulu: unknown key",
                             "did you mean \"youngs_modulus\"", "required"}));
  json top = exampleScene();
  top["objets"] = top["objects"];
  EXPECT_TRUE(contains(error(without(top, "/objects")),
                       {"scene.json: objets: unknown key", "did you mean \"objects\""}));
  // With nothing like it present, the key is reported missing.
  EXPECT_TRUE(contains(error(without(exampleScene(), "/materials/sand/youngs_modulus")),
                       {"scene.json: materials.sand.youngs_modulus: missing required key",
                        "expected a positive number"}));
}

TEST_F(SceneLoaderTest, MisspeltOptionalKeySuggestsTheClosestKey) {
  EXPECT_TRUE(contains(error(with(exampleScene(), "/solver/cfll", 0.3)),
                       {"scene.json: solver.cfll", "unknown key", "did you mean \"cfl\""}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/gravty", json::array({0, 0, 0}))),
                       {"scene.json: gravty", "did you mean \"gravity\""}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/0/velocty", json::array({0, 0, 0}))),
                       {"objects[0].velocty", "did you mean \"velocity\""}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/domain/boundary/frction", 0.1)),
                       {"domain.boundary.frction", "did you mean \"friction\""}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/render/camera/fov", 30)),
                       {"render.camera.fov", "did you mean \"fov_deg\""}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/1/shape/mesh/scael", 2)),
                       {"objects[1].shape.mesh.scael", "did you mean \"scale\""}));
}

TEST_F(SceneLoaderTest, UnknownKeyFarFromEveryKeyListsTheValidOnes) {
  EXPECT_TRUE(contains(error(with(exampleScene(), "/output/compress", true)),
                       {"output.compress", "valid keys here", "\"dir\"", "\"png\""}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/0/shape/cylinder", json::object())),
                       {"objects[0].shape.cylinder", "\"box\"", "\"mesh\"", "\"sphere\""}));
}

TEST_F(SceneLoaderTest, ParameterOfAnotherModelIsAnUnknownKey) {
  json j = exampleScene();
  j["materials"]["jelly"]["friction_angle_deg"] = 30;
  EXPECT_TRUE(contains(error(j), {"materials.jelly.friction_angle_deg", "unknown key",
                                  "model \"fixed_corotated\"", "drucker_prager"}));

  j = exampleScene();
  j["materials"]["water"] = {
      {"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}, {"youngs_modulus", 1e5}};
  EXPECT_TRUE(contains(error(j), {"materials.water.youngs_modulus", "model \"water\""}));

  j = exampleScene();
  j["materials"]["jelly"]["gamma"] = 7;
  EXPECT_TRUE(contains(error(j), {"materials.jelly.gamma", "water"}));
}

TEST_F(SceneLoaderTest, MohrCoulombSandTakesFrictionCohesionAndDilatancy) {
  json j = exampleScene();
  j["materials"]["sand"]["model"] = "mohr_coulomb";
  j["materials"]["sand"]["friction_angle_deg"] = 32;
  j["materials"]["sand"]["cohesion"] = 5;
  j["materials"]["sand"]["dilatancy_angle_deg"] = 4;
  const SceneDesc s = load(j);
  const MaterialDesc& sand = s.materials[1];
  EXPECT_EQ(sand.model, MaterialModel::MohrCoulomb);
  EXPECT_EQ(sand.friction_angle_deg, 32.0);
  EXPECT_EQ(sand.cohesion, 5.0);
  EXPECT_EQ(sand.dilatancy_angle_deg, 4.0);
  // Dilatancy beyond friction is refused, with the range it had.
  j["materials"]["sand"]["dilatancy_angle_deg"] = 40;
  EXPECT_TRUE(contains(error(j), {"materials.sand.dilatancy_angle_deg", "[0, 32]", "got 40"}));
  // mu(I): the grain size turns it on; its other keys alone are refused.
  j["materials"]["sand"]["dilatancy_angle_deg"] = 4;
  j["materials"]["sand"]["grain_diameter"] = 0.001;
  const MaterialDesc rated = load(j).materials[1];
  EXPECT_EQ(rated.grain_diameter, 0.001);
  EXPECT_NEAR(rated.friction_angle_max_deg, 32 + 11.86, 1e-12);
  EXPECT_EQ(rated.inertial_number_i0, 0.279);
  j["materials"]["sand"].erase("grain_diameter");
  j["materials"]["sand"]["friction_angle_max_deg"] = 40;
  EXPECT_TRUE(contains(error(j), {"materials.sand.friction_angle_max_deg", "grain_diameter"}));
  // Drucker-Prager has no dilatancy: the message names the model that does.
  j = exampleScene();
  j["materials"]["sand"]["dilatancy_angle_deg"] = 4;
  EXPECT_TRUE(contains(error(j), {"materials.sand.dilatancy_angle_deg", "unknown key",
                                  "mohr_coulomb"}));
}

TEST_F(SceneLoaderTest, KeyOfAnotherObjectKindIsAnUnknownKey) {
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/0/density", 1000)),
                       {"objects[0].density", "kind \"mpm\"", "only rigid objects"}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/1/material", "sand")),
                       {"objects[1].material", "kind \"rigid\""}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/0/friction", 0.2)),
                       {"objects[0].friction", "kind \"mpm\""}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/3/fixed", true)),
                       {"objects[3].fixed", "kind \"elastic\""}));
}

// Directing a shot: colliders, sinks, sources and their animation.
json shotScene() {
  json j = exampleScene();
  j["objects"].push_back(json::parse(R"({
    "name": "paddle", "kind": "collider", "friction": 0.4,
    "shape": { "box": { "min": [0.4, 0.1, 0.4], "max": [0.6, 0.3, 0.45] } },
    "animation": { "interpolation": "smooth",
                   "keys": [ { "time": 0.0 },
                             { "time": 1.0, "translate": [0.1, 0, 0], "rotate_deg": [0, 90, 0] } ] } })"));
  j["objects"].push_back(json::parse(R"({
    "name": "drain", "kind": "sink",
    "shape": { "sphere": { "center": [0.9, 0.1, 0.9], "radius": 0.05 } } })"));
  j["objects"].push_back(json::parse(R"({
    "name": "hose", "kind": "mpm", "material": "sand", "velocity": [0, -1, 0],
    "shape": { "box": { "min": [0.1, 0.8, 0.1], "max": [0.2, 0.9, 0.2] } },
    "emit": { "start": 0.5, "end": 1.5 },
    "animation": { "keys": [ { "time": 0.5 }, { "time": 1.5, "translate": [0.5, 0, 0] } ] } })"));
  return j;
}

TEST_F(SceneLoaderTest, ReadsCollidersSinksSourcesAndAnimations) {
  const SceneDesc s = load(shotScene());
  const ObjectDesc& paddle = s.objects[4];
  EXPECT_EQ(paddle.kind, ObjectKind::Collider);
  EXPECT_TRUE(paddle.fixed);
  EXPECT_DOUBLE_EQ(paddle.friction, 0.4);
  ASSERT_TRUE(paddle.animation);
  EXPECT_EQ(paddle.animation->interpolation, Interpolation::Smooth);
  ASSERT_EQ(paddle.animation->keys.size(), 2u);
  EXPECT_EQ(paddle.animation->keys[0].translate, (Vec3Desc{0, 0, 0}));
  EXPECT_EQ(paddle.animation->keys[1].rotate_deg, (Vec3Desc{0, 90, 0}));
  EXPECT_EQ(s.objects[5].kind, ObjectKind::Sink);
  EXPECT_FALSE(s.objects[5].animation);
  const ObjectDesc& hose = s.objects[6];
  ASSERT_TRUE(hose.emit);
  EXPECT_DOUBLE_EQ(hose.emit->start, 0.5);
  EXPECT_DOUBLE_EQ(hose.emit->end, 1.5);
  ASSERT_TRUE(hose.animation);
  EXPECT_EQ(hose.animation->interpolation, Interpolation::Linear);
}

TEST_F(SceneLoaderTest, ShotKeysAreCheckedWithTheirPaths) {
  // Keys out of order in time.
  EXPECT_TRUE(contains(error(with(shotScene(), "/objects/4/animation/keys/1/time", 0.0)),
                       {"objects[4].animation.keys[1].time", "increasing time",
                        "keys[0].time = 0"}));
  EXPECT_TRUE(contains(error(with(shotScene(), "/objects/4/animation/keys", json::array())),
                       {"objects[4].animation.keys"}));
  EXPECT_TRUE(contains(error(with(shotScene(), "/objects/4/animation/interpolation", "cubic")),
                       {"objects[4].animation.interpolation", "\"linear\"", "\"smooth\""}));
  EXPECT_TRUE(contains(error(with(shotScene(), "/objects/4/animation/keys/0/rotate", json::array({0, 0, 0}))),
                       {"objects[4].animation.keys[0].rotate", "rotate_deg"}));
  // A collider has no mass and no initial motion.
  EXPECT_TRUE(contains(error(with(shotScene(), "/objects/4/density", 1000)),
                       {"objects[4].density", "kind \"collider\"", "no mass"}));
  EXPECT_TRUE(contains(error(with(shotScene(), "/objects/4/velocity", json::array({1, 0, 0}))),
                       {"objects[4].velocity", "animation"}));
  EXPECT_TRUE(contains(error(with(shotScene(), "/objects/5/friction", 0.3)),
                       {"objects[5].friction", "kind \"sink\""}));
  // emit: an end after its start.
  EXPECT_TRUE(contains(error(with(shotScene(), "/objects/6/emit/end", 0.5)),
                       {"objects[6].emit.end", "after start = 0.5"}));
  EXPECT_TRUE(contains(error(with(shotScene(), "/objects/6/emit/start", -1)),
                       {"objects[6].emit.start"}));
  // Only sources move among MPM objects; only MPM objects emit.
  EXPECT_TRUE(contains(error(without(shotScene(), "/objects/6/emit")),
                       {"objects[6].animation", "\"emit\""}));
  EXPECT_TRUE(contains(error(with(shotScene(), "/objects/2/emit", json{{"end", 1}})),
                       {"objects[2].emit", "only MPM objects"}));
}

TEST_F(SceneLoaderTest, FlipRatioOnlyWithFlipTransfer) {
  EXPECT_TRUE(contains(error(with(exampleScene(), "/solver/flip_ratio", 0.9)),
                       {"solver.flip_ratio", "transfer is \"flip\""}));
}

TEST_F(SceneLoaderTest, ContactReachIsCellsWithinTheStencilAndOnlyWithThreeGrids) {
  EXPECT_EQ(load(exampleScene()).solver.contact_reach, 1.5);
  EXPECT_EQ(load(with(exampleScene(), "/solver/contact_reach", 0.75)).solver.contact_reach, 0.75);
  EXPECT_TRUE(contains(error(with(exampleScene(), "/solver/contact_reach", 2.0)),
                       {"solver.contact_reach", "[0, 1.5]"}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/solver/contact_reach", -0.5)),
                       {"solver.contact_reach"}));
  json single = with(exampleScene(), "/solver/coupling", "single_grid");
  EXPECT_TRUE(contains(error(with(single, "/solver/contact_reach", 0.5)),
                       {"solver.contact_reach", "coupling is \"three_grid\"",
                        "\"single_grid\""}));
}

TEST_F(SceneLoaderTest, FrontFieldsOnlyWithThreeGridsAndApic) {
  EXPECT_FALSE(load(exampleScene()).solver.front_fields);
  const json on = with(exampleScene(), "/solver/front_fields", true);
  EXPECT_TRUE(load(on).solver.front_fields);
  EXPECT_EQ(load(with(on, "/solver/front_angle_deg", 30)).solver.front_angle_deg, 30.0);
  EXPECT_TRUE(contains(error(with(on, "/solver/front_angle_deg", 120)),
                       {"solver.front_angle_deg", "[0, 90]"}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/solver/front_fields", "yes")),
                       {"solver.front_fields"}));
  EXPECT_TRUE(contains(error(with(on, "/solver/transfer", "flip")),
                       {"solver.front_fields", "transfer \"apic\"", "\"flip\""}));
  json single = with(exampleScene(), "/solver/coupling", "single_grid");
  EXPECT_TRUE(contains(error(with(single, "/solver/front_fields", true)),
                       {"solver.front_fields", "coupling is \"three_grid\""}));
}

TEST_F(SceneLoaderTest, ContactNormalIsDistanceOrSamplesAndOnlyWithThreeGrids) {
  EXPECT_EQ(load(exampleScene()).solver.contact_normal, ContactNormal::Distance);
  EXPECT_EQ(load(with(exampleScene(), "/solver/contact_normal", "samples")).solver.contact_normal,
            ContactNormal::Samples);
  EXPECT_TRUE(contains(error(with(exampleScene(), "/solver/contact_normal", "gradient")),
                       {"solver.contact_normal", "distance", "samples"}));
  json single = with(exampleScene(), "/solver/coupling", "single_grid");
  EXPECT_TRUE(contains(error(with(single, "/solver/contact_normal", "samples")),
                       {"solver.contact_normal", "coupling is \"three_grid\""}));
}

TEST_F(SceneLoaderTest, RigidCollisionAndContactGapOnlyWithThreeGrids) {
  const SceneDesc d = load(exampleScene());
  EXPECT_EQ(d.solver.rigid_collision, RigidCollision::Newton);
  EXPECT_TRUE(d.solver.contact_gap);
  EXPECT_EQ(load(with(exampleScene(), "/solver/rigid_collision", "jacobi")).solver.rigid_collision,
            RigidCollision::Jacobi);
  EXPECT_FALSE(load(with(exampleScene(), "/solver/contact_gap", false)).solver.contact_gap);
  EXPECT_TRUE(contains(error(with(exampleScene(), "/solver/rigid_collision", "gauss_seidel")),
                       {"solver.rigid_collision", "jacobi", "newton"}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/solver/contact_gap", "yes")),
                       {"solver.contact_gap"}));
  json single = with(exampleScene(), "/solver/coupling", "single_grid");
  EXPECT_TRUE(contains(error(with(single, "/solver/rigid_collision", "jacobi")),
                       {"solver.rigid_collision", "coupling is \"three_grid\""}));
  EXPECT_TRUE(contains(error(with(single, "/solver/contact_gap", true)),
                       {"solver.contact_gap", "coupling is \"three_grid\""}));
}

TEST_F(SceneLoaderTest, MisspeltChoiceSuggestsTheClosest) {
  EXPECT_TRUE(contains(error(with(exampleScene(), "/domain/boundary/type", "slpi")),
                       {"domain.boundary.type", "\"slip\", \"sticky\", \"separate\"",
                        "got \"slpi\"", "did you mean \"slip\""}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/materials/sand/model", "drucker-prager")),
                       {"materials.sand.model", "did you mean \"drucker_prager\""}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/2/kind", "rigit")),
                       {"objects[2].kind", "did you mean \"rigid\""}));
}

// References and names

TEST_F(SceneLoaderTest, UnknownMaterialReferenceListsTheKnownOnes) {
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/0/material", "snad")),
                       {"scene.json: objects[0].material", "\"snad\"", "\"jelly\", \"sand\"",
                        "did you mean \"sand\""}));
  EXPECT_TRUE(contains(error(without(exampleScene(), "/objects/3/material")),
                       {"objects[3].material", "missing required key"}));
}

TEST_F(SceneLoaderTest, ElasticObjectNeedsAnElasticMaterial) {
  EXPECT_TRUE(
      contains(error(with(exampleScene(), "/objects/3/material", "sand")),
               {"objects[3].material", "fixed_corotated or neo_hookean", "drucker_prager"}));
}

TEST_F(SceneLoaderTest, DuplicateObjectNamesAreAnError) {
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/2/name", "pile")),
                       {"scene.json: objects[2].name", "\"pile\"", "objects[0]"}));
}

TEST_F(SceneLoaderTest, NamesMustBeSafeForFiles) {
  EXPECT_TRUE(contains(error(with(exampleScene(), "/name", "my scene")),
                       {"scene.json: name", "\"my scene\"", "A-Z"}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/name", "..")), {"scene.json: name"}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/1/name", "a/b")), {"objects[1].name"}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/name", "")), {"name", "non-empty"}));
}

TEST_F(SceneLoaderTest, HydrostaticStartOnlyForWaterAtRest) {
  json j = exampleScene();
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}};
  j["objects"][0]["material"] = "water";
  EXPECT_EQ(load(j).objects[0].initial_pressure, InitialPressure::None);
  EXPECT_EQ(load(with(j, "/objects/0/initial_pressure", "hydrostatic")).objects[0].initial_pressure,
            InitialPressure::Hydrostatic);
  EXPECT_EQ(load(with(j, "/objects/0/initial_pressure", "none")).objects[0].initial_pressure,
            InitialPressure::None);
  EXPECT_TRUE(contains(error(with(j, "/objects/0/initial_pressure", "hydrostatik")),
                       {"objects[0].initial_pressure", "\"hydrostatic\""}));
  // Sand has no pressure of its own to start from; a source's water moves.
  EXPECT_TRUE(
      contains(error(with(exampleScene(), "/objects/0/initial_pressure", "hydrostatic")),
               {"objects[0].initial_pressure", "water material", "\"sand\"", "drucker_prager"}));
  json source = with(j, "/objects/0/initial_pressure", "hydrostatic");
  source["objects"][0]["emit"] = {{"start", 0}, {"end", 1}};
  EXPECT_TRUE(contains(error(source), {"objects[0].initial_pressure", "source"}));
  // objects[2] of the example scene is a rigid ball.
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/2/initial_pressure", "hydrostatic")),
                       {"objects[2].initial_pressure", "only MPM objects of a water material"}));
}

TEST_F(SceneLoaderTest, IntegratorOnlyForElasticObjects) {
  // objects[2] of the example scene is a rigid ball.
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/2/integrator", "implicit")),
                       {"objects[2].integrator", "only elastic objects take it"}));
}

TEST_F(SceneLoaderTest, DampingForExplicitElasticObjects) {
  // objects[3] of the example scene is an elastic cube, objects[2] a rigid ball.
  EXPECT_EQ(load(exampleScene()).objects[3].damping, 0.0);
  EXPECT_EQ(load(with(exampleScene(), "/objects/3/damping", 20)).objects[3].damping, 20.0);
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/3/damping", -1)),
                       {"objects[3].damping", "non-negative"}));
  json implicit = with(exampleScene(), "/objects/3/integrator", "implicit");
  EXPECT_TRUE(contains(error(with(implicit, "/objects/3/damping", 20)),
                       {"objects[3].damping", "backward Euler"}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/2/damping", 20)),
                       {"objects[2].damping", "only elastic objects take it"}));
}

TEST_F(SceneLoaderTest, SampleSpacingForSolidsWithinDxOverEightToDx) {
  // Left out: 0, the sampler's dx/2. The bounds themselves are allowed.
  EXPECT_EQ(load(exampleScene()).objects[3].sample_spacing, 0.0);
  EXPECT_EQ(load(with(exampleScene(), "/objects/3/sample_spacing", 0.01)).objects[3].sample_spacing,
            0.01);
  EXPECT_EQ(
      load(with(exampleScene(), "/objects/2/sample_spacing", 0.00125)).objects[2].sample_spacing,
      0.00125);
  // MPM objects are sampled by particles_per_cell.
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/0/sample_spacing", 0.005)),
                       {"objects[0].sample_spacing", "unknown key", "particles_per_cell"}));
}

TEST_F(SceneLoaderTest, ObjectNamesMustBeSafeForFiles) {
  // A rigid object's name names its files: bodies/NAME.FFFF.ply.
  for (const char* bad : {"", ".", "..", "my ball", "a/b", "a\\b", "b\xC3\xA4ll", "ball*", "x:y"})
    EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/2/name", bad)),
                         {"scene.json: objects[2].name"}))
        << "name \"" << bad << "\"";
  EXPECT_EQ(load(with(exampleScene(), "/objects/2/name", "Ball-2.v_3")).objects[2].name,
            "Ball-2.v_3");
  // Names that differ only in case would share files where case is ignored.
  json j = exampleScene();
  const std::string first = j["objects"][0]["name"];
  std::string upper = first;
  for (char& ch : upper) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  EXPECT_TRUE(contains(error(with(j, "/objects/2/name", upper)),
                       {"scene.json: objects[2].name", "unique among objects (ignoring case)"}));
}

// Types and ranges

struct BadValue {
  std::string pointer;  // JSON pointer of the value to replace
  json value;
  std::vector<std::string> expected;  // substrings of the message
};

void PrintTo(const BadValue& b, std::ostream* os) {
  *os << b.pointer << " = " << b.value.dump();
}

class BadValueTest : public SceneLoaderTest, public ::testing::WithParamInterface<BadValue> {};

TEST_P(BadValueTest, IsAnInputErrorNamingKeyAndValue) {
  const BadValue& b = GetParam();
  const std::string msg = error(with(exampleScene(), b.pointer, b.value));
  EXPECT_TRUE(contains(msg, {"scene.json"}));
  for (const std::string& part : b.expected) EXPECT_TRUE(contains(msg, {part}));
}

INSTANTIATE_TEST_SUITE_P(
    WrongTypes, BadValueTest,
    ::testing::Values(
        BadValue{"/version", "1", {"version", "expected an integer", "a string (\"1\")"}},
        BadValue{"/domain/dx", "0.01", {"domain.dx", "expected a positive number", "string"}},
        BadValue{"/gravity",
                 json::array({0, -9.81}),
                 {"gravity", "expected an array of 3 numbers", "array of 2 elements"}},
        BadValue{"/domain/min", "origin", {"domain.min", "array of 3 numbers", "a string"}},
        BadValue{"/domain/max", json::array({1, "1", 1}), {"domain.max", "array of 3 numbers"}},
        BadValue{"/objects/1/fixed", 1, {"objects[1].fixed", "expected true or false", "got 1"}},
        BadValue{"/output/png", "yes", {"output.png", "true or false"}},
        BadValue{"/output/dir", 3, {"output.dir", "expected a string", "got 3"}},
        BadValue{"/materials", json::array(), {"materials", "expected an object"}},
        BadValue{"/materials/sand", 3, {"materials.sand", "expected an object", "got 3"}},
        BadValue{"/objects", json::object(), {"objects", "expected an array of objects"}},
        BadValue{"/objects/0", "pile", {"objects[0]", "expected an object"}},
        BadValue{"/objects/0/shape", json::array(), {"objects[0].shape", "expected an object"}},
        BadValue{"/render/resolution",
                 json::array({640.5, 360}),
                 {"render.resolution[0]", "expected an integer", "640.5"}},
        BadValue{"/solver/transfer", 1, {"solver.transfer", "expected one of", "got 1"}},
        BadValue{"/frames", 48, {"frames", "expected an object", "got 48"}}));

INSTANTIATE_TEST_SUITE_P(
    OutOfRange, BadValueTest,
    ::testing::Values(
        BadValue{"/version", 2, {"version", "expected 1", "got 2"}},
        BadValue{"/domain/dx", -0.01, {"domain.dx", "expected a positive number, got -0.01"}},
        BadValue{"/domain/dx", 0.3, {"domain.dx", "at least 4 cells", "0.25"}},
        BadValue{"/domain/dx", 1e-9, {"domain.dx", "at most 4194304 cells"}},
        BadValue{"/domain/max", json::array({1, 0, 1}), {"domain.max", "greater than min"}},
        BadValue{"/domain/boundary/friction", -1, {"domain.boundary.friction", "non-negative"}},
        BadValue{"/frames/count", -1, {"frames.count", "non-negative integer", "got -1"}},
        BadValue{"/frames/count", 2.5, {"frames.count", "integer", "got 2.5"}},
        BadValue{"/frames/fps", 0, {"frames.fps", "positive"}},
        BadValue{"/solver/cfl", 1.5, {"solver.cfl", "in (0, 1]", "got 1.5"}},
        BadValue{"/solver/cfl", 0, {"solver.cfl", "in (0, 1]"}},
        BadValue{"/solver/max_dt", 0, {"solver.max_dt", "positive"}},
        BadValue{"/solver/particles_per_cell", 0, {"solver.particles_per_cell", "[1, 64]"}},
        BadValue{"/solver/particles_per_cell", 65, {"solver.particles_per_cell", "got 65"}},
        BadValue{"/solver/particles_per_cell", 8.5, {"solver.particles_per_cell", "got 8.5"}},
        BadValue{"/solver/particles_per_cell", 1e12, {"particles_per_cell", "integer"}},
        BadValue{"/solver/elastic_contact_passes",
                 -1,
                 {"solver.elastic_contact_passes", "[0, 100]", "got -1"}},
        BadValue{"/materials/sand/density", 0, {"materials.sand.density", "positive", "got 0"}},
        BadValue{
            "/materials/sand/youngs_modulus", -5, {"materials.sand.youngs_modulus", "positive"}},
        BadValue{"/materials/jelly/poisson_ratio",
                 0.5,
                 {"materials.jelly.poisson_ratio", "in [0, 0.5)", "got 0.5"}},
        BadValue{"/materials/sand/friction_angle_deg",
                 90,
                 {"materials.sand.friction_angle_deg", "[0, 90)"}},
        BadValue{"/materials/sand/cohesion", -1, {"materials.sand.cohesion", "non-negative"}},
        BadValue{"/objects/1/density", -2500, {"objects[1].density", "positive"}},
        BadValue{"/objects/2/friction", -0.1, {"objects[2].friction", "non-negative"}},
        BadValue{"/objects/2/shape/sphere/radius", 0, {"objects[2].shape.sphere.radius"}},
        BadValue{"/objects/0/shape/box/max",
                 json::array({0.4, 0.0, 0.4}),
                 {"objects[0].shape.box.max", "greater than min"}},
        BadValue{"/objects/1/shape/mesh/scale", 0, {"objects[1].shape.mesh.scale", "positive"}},
        BadValue{"/objects/3/sample_spacing",
                 0.011,
                 {"objects[3].sample_spacing", "in [dx/8, dx] = [0.00125, 0.01]", "got 0.011"}},
        BadValue{"/objects/2/sample_spacing",
                 0.001,
                 {"objects[2].sample_spacing", "[dx/8, dx]", "domain.dx = 0.01", "got 0.001"}},
        BadValue{"/objects/3/sample_spacing", -0.005, {"objects[3].sample_spacing", "positive"}},
        BadValue{
            "/objects/1/velocity", json::array({1, 0, 0}), {"objects[1].velocity", "fixed object"}},
        BadValue{"/render/resolution",
                 json::array({8, 360}),
                 {"render.resolution[0]", "[16, 8192]", "got 8"}},
        BadValue{"/render/camera/fov_deg", 180, {"render.camera.fov_deg", "(0, 180)"}},
        BadValue{"/render/camera/target",
                 json::array({2.0, 1.2, 2.0}),
                 {"render.camera.target", "other than eye"}}));

TEST(SceneMaterialRanges, SnowAndWaterParametersAreChecked) {
  json j = minimalScene();
  j["materials"]["m"] = {{"model", "snow"},
                         {"density", 400},
                         {"youngs_modulus", 1.4e5},
                         {"poisson_ratio", 0.2},
                         {"critical_compression", 1}};
  EXPECT_TRUE(
      contains(parseError(j), {"virtual.json: materials.m.critical_compression", "(0, 1)"}));
  j["materials"]["m"] = {
      {"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}, {"gamma", 0.5}};
  EXPECT_TRUE(contains(parseError(j), {"materials.m.gamma", "a number >= 1, got 0.5"}));
  j["materials"]["m"].erase("bulk_modulus");
  EXPECT_TRUE(contains(parseError(j), {"materials.m.bulk_modulus", "missing required key"}));
}

// Shapes and files

TEST_F(SceneLoaderTest, MissingMeshFileNamesKeyAndResolvedPath) {
  const std::string msg =
      error(with(exampleScene(), "/objects/1/shape/mesh/path", "meshes/gone.obj"));
  EXPECT_TRUE(contains(msg, {"scene.json: objects[1].shape.mesh.path",
                             (dir_ / "meshes" / "gone.obj").lexically_normal().string()}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/1/shape/mesh/path", "meshes")),
                       {"objects[1].shape.mesh.path", "not a file"}));
}

TEST_F(SceneLoaderTest, ShapeNeedsExactlyOneKind) {
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects/0/shape", json::object())),
                       {"objects[0].shape", "exactly one of", "got none"}));
  json j = with(exampleScene(), "/objects/2/shape/box",
                json::parse(R"({"min": [0, 0, 0], "max": [1, 1, 1]})"));
  EXPECT_TRUE(contains(error(j), {"objects[2].shape", "\"box\" and \"sphere\""}));
  EXPECT_TRUE(contains(error(without(exampleScene(), "/objects/2/shape")),
                       {"objects[2].shape", "missing required key"}));
}

TEST_F(SceneLoaderTest, ShapeMustReachIntoTheDomain) {
  json j = with(exampleScene(), "/objects/0/shape/box/min", json::array({2, 0, 0}));
  j = with(j, "/objects/0/shape/box/max", json::array({3, 1, 1}));
  EXPECT_TRUE(contains(error(j), {"objects[0].shape", "inside the domain"}));
  EXPECT_TRUE(contains(
      error(with(exampleScene(), "/objects/2/shape/sphere/center", json::array({0.5, -0.1, 0.5}))),
      {"objects[2].shape", "inside the domain"}));
  // A sphere poking in from outside is fine.
  EXPECT_NO_THROW(
      load(with(exampleScene(), "/objects/2/shape/sphere/center", json::array({0.5, -0.05, 0.5}))));
}

TEST_F(SceneLoaderTest, RequiredSectionsAndObjects) {
  EXPECT_TRUE(contains(error(without(exampleScene(), "/domain")),
                       {"scene.json: domain", "missing required key"}));
  EXPECT_TRUE(contains(error(without(exampleScene(), "/domain/dx")), {"domain.dx", "missing"}));
  EXPECT_TRUE(contains(error(with(exampleScene(), "/objects", json::array())),
                       {"scene.json: objects", "non-empty array"}));
  EXPECT_TRUE(contains(error(without(exampleScene(), "/version")), {"version", "missing"}));
  EXPECT_TRUE(contains(error(without(exampleScene(), "/objects/1/density")),
                       {"objects[1].density", "missing"}));
}

// The dictionary itself

TEST(ParamDict, EditDistanceAndClosestMatch) {
  EXPECT_EQ(editDistance("", ""), 0u);
  EXPECT_EQ(editDistance("youngs_modulu", "youngs_modulus"), 1u);
  EXPECT_EQ(editDistance("kitten", "sitting"), 3u);
  EXPECT_EQ(editDistance("Density", "density"), 1u);
  EXPECT_EQ(closestMatch("youngs_modulu", {"density", "youngs_modulus"}), "youngs_modulus");
  EXPECT_EQ(closestMatch("dy", {"dx", "min", "max"}), "dx");
  EXPECT_EQ(closestMatch("fov", {"eye", "fov_deg", "target"}), "fov_deg");
  EXPECT_FALSE(closestMatch("compress", {"dir", "ply", "vdb", "png"}).has_value());
}

TEST(ParamDict, RangesDescribeThemselves) {
  EXPECT_EQ(Range::positive().describe(), "a positive number");
  EXPECT_EQ(Range::nonNegative().describe("integer"), "a non-negative integer");
  EXPECT_EQ(Range::closed(1, 64).describe("integer"), "an integer in [1, 64]");
  EXPECT_EQ(Range::closedOpen(0, 0.5).describe(), "a number in [0, 0.5)");
  EXPECT_EQ(Range::atLeast(1).describe(), "a number >= 1");
  EXPECT_TRUE(Range::openClosed(0, 1).contains(1));
  EXPECT_FALSE(Range::openClosed(0, 1).contains(0));
}

TEST(ParamDict, TracksPathsReadsAndUnknownKeys) {
  const json j = json::parse(R"({"a": {"b": [{"c": 1}, {"c": "x"}]}, "d": 2, "e": 3})");
  const ParamDict root(j, "f.json");
  const ParamDict a = root.requireDict("a");
  const std::vector<ParamDict> items = a.requireDictArray("b");
  ASSERT_EQ(items.size(), 2u);
  EXPECT_EQ(items[1].where("c"), "f.json: a.b[1].c");
  EXPECT_EQ(items[0].requireInt("c"), 1);
  EXPECT_THROW(items[1].requireInt("c"), InputError);
  EXPECT_EQ(root.getDouble("d", 0), 2.0);
  EXPECT_EQ(root.getDouble("missing", 5), 5.0);
  EXPECT_EQ(root.unknownKeys(), std::vector<std::string>{"e"});
  try {
    root.checkUnknownKeys();
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where(), "f.json: e");
  }
  // Copies share the record of what was read.
  const ParamDict copy = root;
  (void)copy.has("e");
  EXPECT_NO_THROW(root.checkUnknownKeys());
}

}  // namespace
}  // namespace triad
