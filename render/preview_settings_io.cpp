#include "render/preview_settings_io.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "sim/errors.h"
#include "sim/frame_name.h"

namespace triad::render {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {


json vec(const Vec3& v) { return json::array({v[0], v[1], v[2]}); }

// Small checked readers: each names the file and key path on failure.
struct Reader {
  std::string file;
  [[noreturn]] void bad(const std::string& key, const std::string& what) const {
    throw InputError(file + ": " + key, what);
  }
  const json& get(const json& j, const std::string& key, const std::string& path) const {
    if (!j.is_object() || !j.contains(key)) bad(path, "missing");
    return j.at(key);
  }
  double number(const json& j, const std::string& path) const {
    if (!j.is_number()) bad(path, "expected a number");
    return j.get<double>();
  }
  Vec3 vec3(const json& j, const std::string& path) const {
    if (!j.is_array() || j.size() != 3) bad(path, "expected an array of 3 numbers");
    Vec3 v;
    for (size_t i = 0; i < 3; ++i) v[i] = number(j[i], path + "[" + std::to_string(i) + "]");
    return v;
  }
};

// The legend's lines and the surface colours: [{NAME_KEY: string, "color":
// [r, g, b]}] under `key`.
json swatchesJson(const std::vector<LegendEntry>& entries, const char* name_key) {
  json out = json::array();
  for (const LegendEntry& e : entries) out.push_back({{name_key, e.label}, {"color", e.color}});
  return out;
}

std::vector<LegendEntry> readSwatches(const Reader& r, const json& j, const std::string& key,
                                      const std::string& name_key) {
  std::vector<LegendEntry> out;
  if (!j.contains(key)) return out;
  const std::string shape = "{\"" + name_key + "\": string, \"color\": [r, g, b]}";
  const json& entries = j[key];
  if (!entries.is_array()) r.bad(key, "expected an array of " + shape);
  for (size_t i = 0; i < entries.size(); ++i) {
    const std::string at = key + "[" + std::to_string(i) + "]";
    const json& e = entries[i];
    if (!e.is_object() || !e.contains(name_key) || !e[name_key].is_string()) r.bad(at, "expected " + shape);
    const Vec3 c = r.vec3(r.get(e, "color", at + ".color"), at + ".color");
    out.push_back({e[name_key].get<std::string>(), {float(c[0]), float(c[1]), float(c[2])}});
  }
  return out;
}

}  // namespace

std::array<float, 3> materialColor(MaterialModel model, int first_object) {
  switch (model) {
    case MaterialModel::Water: return {0.10f, 0.33f, 0.80f};
    case MaterialModel::DruckerPrager:
    case MaterialModel::MohrCoulomb: return {0.72f, 0.56f, 0.33f};
    case MaterialModel::Snow: return {0.90f, 0.92f, 0.95f};
    default: return objectColor(first_object);
  }
}

PreviewSettings previewSettingsForScene(const SceneDesc& scene) {
  PreviewSettings s;
  s.width = scene.render.resolution[0];
  s.height = scene.render.resolution[1];
  s.supersample = scene.render.supersample;
  s.domain = {scene.domain.min, scene.domain.max};
  if (scene.render.camera) {
    s.camera = {scene.render.camera->eye, scene.render.camera->target, scene.render.camera->fov_deg};
    s.camera_automatic = false;
  } else {
    s.camera = autoCamera(s.domain, double(s.width) / std::max(1, s.height));
    s.camera_automatic = true;
  }
  s.particle_radius = particleRadius(scene.domain.dx, scene.solver.particles_per_cell);
  for (const ObjectDesc& o : scene.objects) s.object_names.push_back(o.name);

  // The legend: what is drawn, in the colour it is drawn in.
  const bool surfaces = scene.render.style == RenderStyle::Surface;
  std::vector<LegendEntry> legend;
  std::vector<int> materials_listed;
  for (size_t k = 0; k < scene.objects.size(); ++k) {
    const ObjectDesc& o = scene.objects[k];
    if (o.kind == ObjectKind::Sink) continue;
    if (o.kind == ObjectKind::Mpm && surfaces) {
      if (std::find(materials_listed.begin(), materials_listed.end(), o.material) !=
          materials_listed.end())
        continue;
      materials_listed.push_back(o.material);
      const MaterialDesc& m = scene.materials[size_t(o.material)];
      legend.push_back({m.name, materialColor(m.model, int(k))});
      s.surfaces.push_back(legend.back());
    } else {
      legend.push_back({o.name, objectColor(int(k))});
    }
  }
  constexpr size_t kMaxLines = 12;
  if (legend.size() > kMaxLines) {
    const size_t more = legend.size() - (kMaxLines - 1);
    legend.resize(kMaxLines - 1);
    legend.push_back({"+" + std::to_string(more) + " more", {0.0f, 0.0f, 0.0f}});
  }
  if (scene.render.legend) s.legend = std::move(legend);
  return s;
}

std::string previewSettingsPath(const std::string& out_dir) {
  return out_dir + "/preview/settings.json";
}

std::string previewImagePath(const std::string& out_dir, int frame) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%04d", frame);
  return out_dir + "/preview/preview." + buf + ".png";
}

std::map<int, std::string> listFrameFiles(const std::string& dir, const std::string& stem,
                                          const std::string& ext) {
  std::map<int, std::string> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    FrameName n;
    if (parseFrameName(e.path().filename().string(), n) && n.stem == stem && n.ext == ext)
      out[n.frame] = e.path().string();
  }
  return out;
}

std::string contactSheetPath(const std::string& out_dir) {
  return out_dir + "/preview/contact_sheet.png";
}

void writePreviewSettings(const std::string& out_dir, const PreviewSettings& s,
                          const std::string& scene_name) {
  const std::string path = previewSettingsPath(out_dir);
  std::error_code ec;
  fs::create_directories(fs::path(path).parent_path(), ec);
  if (ec) throw std::runtime_error(out_dir + "/preview: cannot create: " + ec.message());
  json j;
  j["version"] = 1;
  if (!scene_name.empty()) j["scene"] = scene_name;
  j["resolution"] = {s.width, s.height};
  j["supersample"] = s.supersample;
  j["camera"] = {{"eye", vec(s.camera.eye)},
                 {"target", vec(s.camera.target)},
                 {"fov_deg", s.camera.fov_deg},
                 {"automatic", s.camera_automatic}};
  j["domain"] = {{"min", vec(s.domain.min)}, {"max", vec(s.domain.max)}};
  j["particle_radius"] = s.particle_radius;
  j["domain_outline"] = s.domain_outline;
  j["objects"] = s.object_names;
  j["legend"] = swatchesJson(s.legend, "label");
  j["surfaces"] = swatchesJson(s.surfaces, "material");
  const std::string tmp = path + ".tmp" + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << j.dump(2) << "\n";
    out.flush();
    if (!out) {
      std::remove(tmp.c_str());
      throw std::runtime_error(path + ": cannot write");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw std::runtime_error(path + ": cannot write (rename failed)");
  }
}

PreviewSettings readPreviewSettings(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open the preview settings");
  json j;
  try {
    j = json::parse(in);
  } catch (const json::exception& e) {
    throw InputError(path, std::string("not valid JSON: ") + e.what());
  }
  const Reader r{path};
  PreviewSettings s;
  const json& res = r.get(j, "resolution", "resolution");
  if (!res.is_array() || res.size() != 2 || !res[0].is_number_integer() ||
      !res[1].is_number_integer() || res[0].get<int>() < 1 || res[1].get<int>() < 1 ||
      res[0].get<int>() > 8192 || res[1].get<int>() > 8192)
    r.bad("resolution", "expected [width, height], two integers in 1..8192");
  s.width = res[0].get<int>();
  s.height = res[1].get<int>();
  if (j.contains("supersample")) {
    const json& ss = j["supersample"];
    if (!ss.is_number_integer() || ss.get<int>() < 1 || ss.get<int>() > 8)
      r.bad("supersample", "expected an integer in 1..8");
    s.supersample = ss.get<int>();
  }
  const json& cam = r.get(j, "camera", "camera");
  s.camera.eye = r.vec3(r.get(cam, "eye", "camera.eye"), "camera.eye");
  s.camera.target = r.vec3(r.get(cam, "target", "camera.target"), "camera.target");
  s.camera.fov_deg = r.number(r.get(cam, "fov_deg", "camera.fov_deg"), "camera.fov_deg");
  if (!(s.camera.fov_deg > 0 && s.camera.fov_deg < 180)) r.bad("camera.fov_deg", "expected 0 < fov_deg < 180");
  if (cam.contains("automatic") && cam["automatic"].is_boolean())
    s.camera_automatic = cam["automatic"].get<bool>();
  const json& dom = r.get(j, "domain", "domain");
  s.domain.min = r.vec3(r.get(dom, "min", "domain.min"), "domain.min");
  s.domain.max = r.vec3(r.get(dom, "max", "domain.max"), "domain.max");
  for (size_t i = 0; i < 3; ++i)
    if (!(s.domain.max[i] > s.domain.min[i])) r.bad("domain", "expected max > min on every axis");
  s.particle_radius = float(r.number(r.get(j, "particle_radius", "particle_radius"), "particle_radius"));
  if (!(s.particle_radius > 0)) r.bad("particle_radius", "expected a positive number");
  if (j.contains("domain_outline") && j["domain_outline"].is_boolean())
    s.domain_outline = j["domain_outline"].get<bool>();
  if (j.contains("objects")) {
    const json& objs = j["objects"];
    if (!objs.is_array()) r.bad("objects", "expected an array of names");
    for (const json& o : objs) {
      if (!o.is_string()) r.bad("objects", "expected an array of names");
      s.object_names.push_back(o.get<std::string>());
    }
  }
  s.legend = readSwatches(r, j, "legend", "label");
  s.surfaces = readSwatches(r, j, "surfaces", "material");
  return s;
}

}  // namespace triad::render
