#include "render/preview_renderer.h"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/osmesa.h>
#include <GL/glext.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "render/gl_context.h"

namespace triad::render {

namespace {

// Tableau 10, with the grey replaced by a cyan so no object looks like the ground.
constexpr float kPalette[kPaletteSize][3] = {
    {0.306f, 0.475f, 0.655f}, {0.949f, 0.557f, 0.169f}, {0.882f, 0.341f, 0.349f},
    {0.463f, 0.718f, 0.698f}, {0.349f, 0.631f, 0.310f}, {0.929f, 0.788f, 0.282f},
    {0.690f, 0.478f, 0.631f}, {1.000f, 0.616f, 0.655f}, {0.612f, 0.459f, 0.373f},
    {0.090f, 0.745f, 0.812f}};

// Particles drawn per batch (below).
constexpr size_t kParticleBatch = size_t(1) << 16;
// Draw-order keys go to and come from GL as two 32-bit words, low first.
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "keys are passed as two words");
constexpr float kBackgroundTop[3] = {0.60f, 0.64f, 0.70f};
constexpr float kBackgroundBottom[3] = {0.84f, 0.85f, 0.86f};

// Lighting shared by every lit surface: a key light from the upper left of the
// camera, a sky/ground hemisphere term and a weak highlight. View space.
const char* kShadeGlsl = R"(
uniform vec3 light_dir;  // view space, unit, towards the light
uniform vec3 sky_dir;    // world +y in view space
vec3 shade(vec3 albedo, vec3 n, vec3 v) {
  float diff = max(dot(n, light_dir), 0.0);
  float hemi = 0.5 + 0.5 * dot(n, sky_dir);
  vec3 h = normalize(light_dir + v);
  float spec = pow(max(dot(n, h), 0.0), 40.0) * 0.2;
  return albedo * (0.16 + 0.22 * hemi + 0.62 * diff) + vec3(spec);
}
)";

const char* kParticleVs = R"(#version 330 core
layout(location = 0) in vec3 center;
layout(location = 1) in uint object;
layout(location = 2) in uvec2 key;  // draw order, for compositing layers
uniform mat4 view;
uniform mat4 proj;
uniform float radius;
uniform vec3 palette[10];
flat out vec3 c_view;
flat out vec3 albedo;
flat out uvec2 k;
out vec3 p_view;
void main() {
  k = key;
  vec2 corner = vec2((gl_VertexID & 1) != 0 ? 1.0 : -1.0, (gl_VertexID & 2) != 0 ? 1.0 : -1.0);
  vec3 c = (view * vec4(center, 1.0)).xyz;
  float d = length(c);
  c_view = c;
  albedo = palette[object % 10u];
  if (d <= radius * 1.001) {  // the eye is inside the sphere: draw nothing
    p_view = vec3(0.0);
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    return;
  }
  // A square facing the eye at the sphere's front: it covers the silhouette.
  vec3 w = c / d;
  vec3 up = abs(w.y) < 0.99 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
  vec3 r = normalize(cross(w, up));
  vec3 u = cross(r, w);
  vec3 q = c - w * radius + (r * corner.x + u * corner.y) * radius;
  p_view = q;
  gl_Position = proj * vec4(q, 1.0);
}
)";

const char* kParticleFs = R"(
flat in vec3 c_view;
flat in vec3 albedo;
flat in uvec2 k;
in vec3 p_view;
uniform mat4 proj;
uniform float radius;
layout(location = 0) out vec4 frag;
layout(location = 1) out uvec2 tag;
void main() {
  tag = k;
  // Ray from the eye through this fragment against the sphere.
  vec3 dir = normalize(p_view);
  float b = dot(dir, c_view);
  vec3 h = c_view - dir * b;  // centre to its closest point on the ray
  float disc = radius * radius - dot(h, h);
  if (disc < 0.0) discard;
  vec3 hit = dir * (b - sqrt(disc));
  vec3 n = (hit - c_view) / radius;
  vec4 clip = proj * vec4(hit, 1.0);
  gl_FragDepth = clamp(clip.z / clip.w * 0.5 + 0.5, 0.0, 1.0);
  frag = vec4(shade(albedo, n, -dir), 1.0);
}
)";

const char* kMeshVs = R"(#version 330 core
layout(location = 0) in vec3 pos;
layout(location = 1) in vec3 normal;
uniform mat4 view;
uniform mat4 proj;
out vec3 p_view;
out vec3 n_view;
void main() {
  vec4 p = view * vec4(pos, 1.0);
  p_view = p.xyz;
  n_view = mat3(view) * normal;
  gl_Position = proj * p;
}
)";

const char* kMeshFs = R"(
in vec3 p_view;
in vec3 n_view;
uniform vec3 color;
layout(location = 0) out vec4 frag;
layout(location = 1) out uvec2 tag;
void main() {
  tag = uvec2(0u);
  vec3 v = normalize(-p_view);
  vec3 n = normalize(n_view);
  if (dot(n, v) < 0.0) n = -n;  // two-sided
  frag = vec4(shade(color, n, v), 1.0);
}
)";

const char* kGroundVs = R"(#version 330 core
layout(location = 0) in vec3 pos;
uniform mat4 view;
uniform mat4 proj;
out vec2 xz;
void main() {
  xz = pos.xz;
  gl_Position = proj * view * vec4(pos, 1.0);
}
)";

const char* kGroundFs = R"(#version 330 core
in vec2 xz;
uniform vec2 dom_min;
uniform vec2 dom_max;
uniform float cell;
uniform float fade;
uniform vec3 far_color;
layout(location = 0) out vec4 frag;
layout(location = 1) out uvec2 tag;
void main() {
  tag = uvec2(0u);
  vec2 c = floor(xz / cell);
  float parity = mod(c.x + c.y, 2.0);
  vec3 col = mix(vec3(0.56, 0.56, 0.55), vec3(0.66, 0.66, 0.65), parity);
  vec2 o = max(max(dom_min - xz, xz - dom_max), vec2(0.0));
  float t = clamp(length(o) / fade, 0.0, 1.0);
  frag = vec4(mix(col, far_color, t), 1.0);
}
)";

const char* kFlatVs = R"(#version 330 core
layout(location = 0) in vec3 pos;
uniform mat4 view;
uniform mat4 proj;
void main() { gl_Position = proj * view * vec4(pos, 1.0); }
)";

const char* kFlatFs = R"(#version 330 core
uniform vec3 color;
layout(location = 0) out vec4 frag;
layout(location = 1) out uvec2 tag;
void main() {
  frag = vec4(color, 1.0);
  tag = uvec2(0xFFFFFFFFu);  // the outline: drawn after every particle
}
)";

const char* kBackgroundVs = R"(#version 330 core
out float t;
void main() {
  vec2 p = vec2((gl_VertexID == 1) ? 3.0 : -1.0, (gl_VertexID == 2) ? 3.0 : -1.0);
  t = p.y * 0.5 + 0.5;
  gl_Position = vec4(p, 0.0, 1.0);
}
)";

const char* kBackgroundFs = R"(#version 330 core
in float t;
uniform vec3 top;
uniform vec3 bottom;
layout(location = 0) out vec4 frag;
layout(location = 1) out uvec2 tag;
void main() {
  frag = vec4(mix(bottom, top, clamp(t, 0.0, 1.0)), 1.0);
  tag = uvec2(0u);
}
)";

std::string litFragment(const char* body) { return std::string("#version 330 core\n") + kShadeGlsl + body; }

void checkKeys(const uint64_t* keys, size_t count) {
  for (size_t i = 0; i < count; ++i)
    if (keys[i] < kFirstParticleKey || keys[i] == kOutlineKey || (i > 0 && keys[i] <= keys[i - 1]))
      throw std::runtime_error("preview layer: particle keys must ascend within (" +
                               std::to_string(kFirstParticleKey) + ", 2^64 - 1)");
}

double niceStep(double x) {
  const double p = std::pow(10.0, std::floor(std::log10(x)));
  const double m = x / p;
  return (m < 1.5 ? 1.0 : m < 3.5 ? 2.0 : m < 7.5 ? 5.0 : 10.0) * p;
}

}  // namespace

std::array<float, 3> objectColor(int index) {
  const int i = ((index % kPaletteSize) + kPaletteSize) % kPaletteSize;
  return {kPalette[i][0], kPalette[i][1], kPalette[i][2]};
}

float particleRadius(double dx, int particles_per_cell) {
  return float(0.5 * dx * std::pow(double(std::max(1, particles_per_cell)), -1.0 / 3.0));
}

struct PreviewRenderer::Impl {
  PreviewSettings settings;
  GlContext gl;
  GLuint vao = 0, particle_vbo = 0, object_vbo = 0, mesh_vbo = 0, ground_vbo = 0, box_vbo = 0;
  GLuint key_vbo = 0;
  GLuint fbo = 0, color_rb = 0, depth_rb = 0;
  GLuint key_rb = 0;  // the layers' draw-order keys; made for the first layer
  int fb_w = 0, fb_h = 0, key_w = 0, key_h = 0;
  GLuint particle_prog = 0, mesh_prog = 0, ground_prog = 0, flat_prog = 0, bg_prog = 0;
  std::vector<uint8_t> pixels;
  std::vector<float> scratch;

  void setup() {
    particle_prog = compileProgram("particles", kParticleVs, litFragment(kParticleFs));
    mesh_prog = compileProgram("meshes", kMeshVs, litFragment(kMeshFs));
    ground_prog = compileProgram("ground", kGroundVs, kGroundFs);
    flat_prog = compileProgram("outline", kFlatVs, kFlatFs);
    bg_prog = compileProgram("background", kBackgroundVs, kBackgroundFs);
    glGenVertexArrays(1, &vao);
    GLuint bufs[6];
    glGenBuffers(6, bufs);
    particle_vbo = bufs[0];
    object_vbo = bufs[1];
    mesh_vbo = bufs[2];
    ground_vbo = bufs[3];
    box_vbo = bufs[4];
    key_vbo = bufs[5];
    glGenFramebuffers(1, &fbo);
    glGenRenderbuffers(1, &color_rb);
    glGenRenderbuffers(1, &depth_rb);
    checkGl("renderer setup");
  }

  void validate(const PreviewSettings& s) {
    if (s.width < 1 || s.height < 1 || s.supersample < 1 || s.supersample > 8)
      throw std::runtime_error("preview: invalid resolution " + std::to_string(s.width) + "x" +
                               std::to_string(s.height) + " or supersampling " +
                               std::to_string(s.supersample));
    GLint max_rb = 0;
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_rb);
    if (s.width * s.supersample > max_rb || s.height * s.supersample > max_rb)
      throw std::runtime_error("preview: " + std::to_string(s.width) + "x" +
                               std::to_string(s.height) + " at " + std::to_string(s.supersample) +
                               "x supersampling exceeds the renderer's limit of " +
                               std::to_string(max_rb) + " pixels");
  }

  void ensureFramebuffer() {
    const int w = settings.width * settings.supersample, h = settings.height * settings.supersample;
    if (w == fb_w && h == fb_h) return;
    glBindRenderbuffer(GL_RENDERBUFFER, color_rb);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
    glBindRenderbuffer(GL_RENDERBUFFER, depth_rb);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, w, h);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color_rb);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_rb);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("preview: the off-screen framebuffer is incomplete");
    checkGl("framebuffer allocation");
    fb_w = w;
    fb_h = h;
  }

  // A second colour attachment for the draw-order keys, only while a layer
  // is drawn (a plain preview needs none: 8 more bytes a pixel).
  void attachKeys(bool on) {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    if (on && (key_w != fb_w || key_h != fb_h)) {
      if (key_rb == 0) glGenRenderbuffers(1, &key_rb);
      glBindRenderbuffer(GL_RENDERBUFFER, key_rb);
      glRenderbufferStorage(GL_RENDERBUFFER, GL_RG32UI, fb_w, fb_h);
      key_w = fb_w;
      key_h = fb_h;
    }
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_RENDERBUFFER,
                              on ? key_rb : 0);
    const GLenum both[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glDrawBuffers(on ? 2 : 1, both);
    if (on && glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("preview: the layer's framebuffer is incomplete");
    checkGl("layer attachment");
  }

  void setCommonUniforms(GLuint prog, const CameraMatrices& m) {
    glUseProgram(prog);
    glUniformMatrix4fv(glGetUniformLocation(prog, "view"), 1, GL_FALSE, m.view.data());
    glUniformMatrix4fv(glGetUniformLocation(prog, "proj"), 1, GL_FALSE, m.proj.data());
    const GLint light = glGetUniformLocation(prog, "light_dir");
    if (light >= 0) {
      const float l[3] = {-0.45f, 0.75f, 0.48f};
      const float n = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
      glUniform3f(light, l[0] / n, l[1] / n, l[2] / n);
      // World +y in view space is the view matrix's second column.
      glUniform3f(glGetUniformLocation(prog, "sky_dir"), m.view[4], m.view[5], m.view[6]);
    }
  }

  // Draws the frame into the framebuffer; `keyed`, also each pixel's
  // draw-order key (the particles' from `keys`; read back by
  // readLayerRows), else reads back the pixels into `pixels`.
  void draw(const PreviewParticles& particles, const std::vector<PreviewMesh>& meshes, bool keyed,
            const uint64_t* keys) {
    gl.makeCurrent();
    ensureFramebuffer();
    attachKeys(keyed);
    const PreviewSettings& s = settings;
    const Box& d = s.domain;
    const double ext_x = d.max[0] - d.min[0], ext_z = d.max[2] - d.min[2];
    const double ext = std::max({ext_x, ext_z, d.max[1] - d.min[1], 1e-6});
    const double margin = 0.75 * ext;
    // The ground: the domain's floor and a margin around it fading out.
    const float gx0 = float(d.min[0] - margin), gx1 = float(d.max[0] + margin);
    const float gz0 = float(d.min[2] - margin), gz1 = float(d.max[2] + margin);
    const float gy = float(d.min[1]);
    Box scene{{gx0, d.min[1], gz0}, {gx1, d.max[1], gz1}};
    for (const PreviewMesh& mesh : meshes)
      for (size_t i = 0; i + 2 < mesh.xyz.size(); i += 3)
        for (int c = 0; c < 3; ++c) {
          scene.min[size_t(c)] = std::min(scene.min[size_t(c)], double(mesh.xyz[i + size_t(c)]));
          scene.max[size_t(c)] = std::max(scene.max[size_t(c)], double(mesh.xyz[i + size_t(c)]));
        }
    const double aspect = double(s.width) / s.height;
    const CameraMatrices m = cameraMatrices(s.camera, aspect, scene);

    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, fb_w, fb_h);
    glBindVertexArray(vao);
    glDisable(GL_BLEND);
    glDisable(GL_CULL_FACE);
    glClearDepth(1.0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    if (keyed) {
      const GLuint none[4] = {0, 0, 0, 0};
      glClearBufferuiv(GL_COLOR, 1, none);
    }

    // Background gradient, behind everything.
    glDisable(GL_DEPTH_TEST);
    glDepthMask(GL_FALSE);
    glUseProgram(bg_prog);
    glUniform3fv(glGetUniformLocation(bg_prog, "top"), 1, kBackgroundTop);
    glUniform3fv(glGetUniformLocation(bg_prog, "bottom"), 1, kBackgroundBottom);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glDepthMask(GL_TRUE);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);

    // Ground plane.
    {
      const float quad[] = {gx0, gy, gz0, gx1, gy, gz0, gx0, gy, gz1, gx1, gy, gz1};
      glBindBuffer(GL_ARRAY_BUFFER, ground_vbo);
      glBufferData(GL_ARRAY_BUFFER, sizeof(quad), quad, GL_STREAM_DRAW);
      glEnableVertexAttribArray(0);
      glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
      glVertexAttribDivisor(0, 0);
      setCommonUniforms(ground_prog, m);
      glUniform2f(glGetUniformLocation(ground_prog, "dom_min"), float(d.min[0]), float(d.min[2]));
      glUniform2f(glGetUniformLocation(ground_prog, "dom_max"), float(d.max[0]), float(d.max[2]));
      glUniform1f(glGetUniformLocation(ground_prog, "cell"), float(niceStep(ext / 10.0)));
      glUniform1f(glGetUniformLocation(ground_prog, "fade"), float(margin));
      glUniform3fv(glGetUniformLocation(ground_prog, "far_color"), 1, kBackgroundBottom);
      // Push the ground back a little so that whatever rests on it wins.
      glEnable(GL_POLYGON_OFFSET_FILL);
      glPolygonOffset(1.0f, 1.0f);
      glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
      glDisable(GL_POLYGON_OFFSET_FILL);
    }

    // Solid meshes, flat-shaded: one vertex per triangle corner with the face normal.
    if (!meshes.empty()) {
      setCommonUniforms(mesh_prog, m);
      const GLint color_loc = glGetUniformLocation(mesh_prog, "color");
      glBindBuffer(GL_ARRAY_BUFFER, mesh_vbo);
      glEnableVertexAttribArray(0);
      glEnableVertexAttribArray(1);
      for (const PreviewMesh& mesh : meshes) {
        const size_t nv = mesh.xyz.size() / 3;
        scratch.clear();
        scratch.reserve(mesh.triangles.size() * 6);
        for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
          const uint32_t idx[3] = {mesh.triangles[t], mesh.triangles[t + 1], mesh.triangles[t + 2]};
          if (idx[0] >= nv || idx[1] >= nv || idx[2] >= nv) continue;
          const float* p[3] = {&mesh.xyz[idx[0] * 3], &mesh.xyz[idx[1] * 3], &mesh.xyz[idx[2] * 3]};
          const float e1[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
          const float e2[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
          float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                        e1[0] * e2[1] - e1[1] * e2[0]};
          const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
          if (!(len > 0.0f)) continue;
          for (float& c : n) c /= len;
          for (int k = 0; k < 3; ++k) {
            scratch.insert(scratch.end(), p[k], p[k] + 3);
            scratch.insert(scratch.end(), n, n + 3);
          }
        }
        if (scratch.empty()) continue;
        const std::array<float, 3> col = mesh.object >= 0 ? objectColor(mesh.object) : mesh.color;
        glUniform3fv(color_loc, 1, col.data());
        glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(scratch.size() * sizeof(float)), scratch.data(),
                     GL_STREAM_DRAW);
        glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
        glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float),
                              reinterpret_cast<const void*>(3 * sizeof(float)));
        glVertexAttribDivisor(0, 0);
        glVertexAttribDivisor(1, 0);
        glDrawArrays(GL_TRIANGLES, 0, GLsizei(scratch.size() / 6));
      }
      glDisableVertexAttribArray(1);
    }

    // Particles: one instanced quad each, the sphere computed per fragment.
    if (particles.count > 0 && particles.xyz && particles.object) {
      setCommonUniforms(particle_prog, m);
      glUniform1f(glGetUniformLocation(particle_prog, "radius"), s.particle_radius);
      glUniform3fv(glGetUniformLocation(particle_prog, "palette"), kPaletteSize, &kPalette[0][0]);
      glBindBuffer(GL_ARRAY_BUFFER, particle_vbo);
      glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(particles.count * 3 * sizeof(float)), particles.xyz,
                   GL_STREAM_DRAW);
      glEnableVertexAttribArray(0);
      glVertexAttribDivisor(0, 1);
      glBindBuffer(GL_ARRAY_BUFFER, object_vbo);
      glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(particles.count * sizeof(uint16_t)), particles.object,
                   GL_STREAM_DRAW);
      glEnableVertexAttribArray(1);
      glVertexAttribDivisor(1, 1);
      if (keyed) {
        // Each key as two words, low first: a little-endian uint64.
        glBindBuffer(GL_ARRAY_BUFFER, key_vbo);
        glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(particles.count * sizeof(uint64_t)), keys,
                     GL_STREAM_DRAW);
        glEnableVertexAttribArray(2);
        glVertexAttribDivisor(2, 1);
      }
      // In batches, each finished before the next (llvmpipe bins a draw's
      // triangles per tile before it rasterises them, and a million
      // particles binned at once held hundreds of MiB); each batch points
      // the attributes at its first particle.
      for (size_t first = 0; first < particles.count; first += kParticleBatch) {
        const GLsizei n = GLsizei(std::min(kParticleBatch, particles.count - first));
        glBindBuffer(GL_ARRAY_BUFFER, particle_vbo);
        glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0,
                              reinterpret_cast<const void*>(first * 3 * sizeof(float)));
        glBindBuffer(GL_ARRAY_BUFFER, object_vbo);
        glVertexAttribIPointer(1, 1, GL_UNSIGNED_SHORT, 0,
                               reinterpret_cast<const void*>(first * sizeof(uint16_t)));
        if (keyed) {
          glBindBuffer(GL_ARRAY_BUFFER, key_vbo);
          glVertexAttribIPointer(2, 2, GL_UNSIGNED_INT, 0,
                                 reinterpret_cast<const void*>(first * 2 * sizeof(uint32_t)));
        }
        glDrawArraysInstanced(GL_TRIANGLE_STRIP, 0, 4, n);
        glFinish();
      }
      glVertexAttribDivisor(0, 0);
      glVertexAttribDivisor(1, 0);
      glDisableVertexAttribArray(1);
      if (keyed) {
        glVertexAttribDivisor(2, 0);
        glDisableVertexAttribArray(2);
      }
    }

    // Domain outline, hidden where material is in front of it.
    if (s.domain_outline) {
      float lines[24 * 3];
      int k = 0;
      for (int a = 0; a < 3; ++a)
        for (int i = 0; i < 4; ++i) {
          const int b = (a + 1) % 3, c = (a + 2) % 3;
          for (int end = 0; end < 2; ++end) {
            float p[3];
            p[a] = float(end ? d.max[size_t(a)] : d.min[size_t(a)]);
            p[b] = float((i & 1) ? d.max[size_t(b)] : d.min[size_t(b)]);
            p[c] = float((i & 2) ? d.max[size_t(c)] : d.min[size_t(c)]);
            for (float v : p) lines[k++] = v;
          }
        }
      glBindBuffer(GL_ARRAY_BUFFER, box_vbo);
      glBufferData(GL_ARRAY_BUFFER, sizeof(lines), lines, GL_STREAM_DRAW);
      glEnableVertexAttribArray(0);
      glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
      glVertexAttribDivisor(0, 0);
      setCommonUniforms(flat_prog, m);
      glUniform3f(glGetUniformLocation(flat_prog, "color"), 0.30f, 0.31f, 0.33f);
      glLineWidth(float(s.supersample));
      glGetError();  // wide lines may be unsupported: then they stay one pixel wide
      glDrawArrays(GL_LINES, 0, 24);
      glLineWidth(1.0f);
    }

    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    if (!keyed) {
      pixels.resize(size_t(fb_w) * fb_h * 4);
      glReadPixels(0, 0, fb_w, fb_h, GL_RGBA, GL_UNSIGNED_BYTE, pixels.data());
    }
    checkGl("preview render");
  }

  // Reads rows y0 .. y0 + rows - 1 of a keyed draw: pixels, depths and keys.
  void readLayerRows(int y0, int rows, uint8_t* rgba, uint32_t* depth, uint64_t* key) {
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glReadPixels(0, y0, fb_w, rows, GL_RGBA, GL_UNSIGNED_BYTE, rgba);
    glReadPixels(0, y0, fb_w, rows, GL_DEPTH_COMPONENT, GL_UNSIGNED_INT, depth);
    glReadBuffer(GL_COLOR_ATTACHMENT1);
    glReadPixels(0, y0, fb_w, rows, GL_RG_INTEGER, GL_UNSIGNED_INT, key);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    checkGl("preview layer");
  }

  // The supersampled pixels box-filtered to the preview's size, legend drawn.
  Image finish(const uint8_t* rgba) const {
    const PreviewSettings& s = settings;
    Image image = downsampleRgbaBottomUp(rgba, s.width, s.height, s.supersample);
    drawLegend(image, s.legend);
    return image;
  }
};

PreviewRenderer::PreviewRenderer(const PreviewSettings& settings) : impl_(new Impl) {
  impl_->setup();
  setSettings(settings);
}

PreviewRenderer::~PreviewRenderer() = default;

const PreviewSettings& PreviewRenderer::settings() const { return impl_->settings; }

void PreviewRenderer::setSettings(const PreviewSettings& settings) {
  impl_->gl.makeCurrent();
  impl_->validate(settings);
  impl_->settings = settings;
}

Image PreviewRenderer::render(const PreviewParticles& particles,
                              const std::vector<PreviewMesh>& meshes) {
  impl_->draw(particles, meshes, false, nullptr);
  return impl_->finish(impl_->pixels.data());
}

PreviewLayer PreviewRenderer::renderLayer(const PreviewParticles& particles,
                                          const std::vector<PreviewMesh>& meshes,
                                          const uint64_t* keys) {
  checkKeys(keys, particles.count);
  impl_->draw(particles, meshes, true, keys);
  PreviewLayer layer;
  layer.width = impl_->fb_w;
  layer.height = impl_->fb_h;
  layer.rgba.resize(4 * layer.pixels());
  layer.depth.resize(layer.pixels());
  layer.key.resize(layer.pixels());
  impl_->readLayerRows(0, layer.height, layer.rgba.data(), layer.depth.data(), layer.key.data());
  return layer;
}

std::vector<LayerPixel> PreviewRenderer::renderParticlePixels(
    const PreviewParticles& particles, const std::vector<PreviewMesh>& meshes,
    const uint64_t* keys) {
  checkKeys(keys, particles.count);
  impl_->draw(particles, meshes, true, keys);
  // A band of rows at a time: no whole layer beside the framebuffer.
  const int w = impl_->fb_w, h = impl_->fb_h, band = 64;
  std::vector<uint8_t> rgba(size_t(w) * band * 4);
  std::vector<uint32_t> depth(size_t(w) * band);
  std::vector<uint64_t> key(size_t(w) * band);
  std::vector<LayerPixel> out;
  for (int y0 = 0; y0 < h; y0 += band) {
    const int rows = std::min(band, h - y0);
    impl_->readLayerRows(y0, rows, rgba.data(), depth.data(), key.data());
    appendParticlePixels(rgba.data(), depth.data(), key.data(), size_t(w) * size_t(rows),
                         uint32_t(size_t(w) * size_t(y0)), out);
  }
  return out;
}

Image PreviewRenderer::finish(const PreviewLayer& layer) const {
  const PreviewSettings& s = impl_->settings;
  if (layer.width != s.width * s.supersample || layer.height != s.height * s.supersample ||
      layer.rgba.size() != 4 * layer.pixels())
    throw std::runtime_error("preview layer: " + std::to_string(layer.width) + "x" +
                             std::to_string(layer.height) + " is not this preview's size");
  return impl_->finish(layer.rgba.data());
}

std::string PreviewRenderer::glDescription() { return impl_->gl.description(); }

}  // namespace triad::render
