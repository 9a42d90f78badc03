#include "render/gl_context.h"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/osmesa.h>
#include <GL/glext.h>

#include <stdexcept>
#include <vector>

namespace triad::render {

GlContext::GlContext() {
  const int attribs[] = {OSMESA_FORMAT,
                         OSMESA_RGBA,
                         OSMESA_DEPTH_BITS,
                         0,
                         OSMESA_STENCIL_BITS,
                         0,
                         OSMESA_ACCUM_BITS,
                         0,
                         OSMESA_PROFILE,
                         OSMESA_CORE_PROFILE,
                         OSMESA_CONTEXT_MAJOR_VERSION,
                         3,
                         OSMESA_CONTEXT_MINOR_VERSION,
                         3,
                         0};
  ctx_ = OSMesaCreateContextAttribs(attribs, nullptr);
  if (!ctx_) throw std::runtime_error("OSMesa: cannot create an OpenGL 3.3 core context");
  makeCurrent();
}

GlContext::~GlContext() {
  if (ctx_) OSMesaDestroyContext(static_cast<OSMesaContext>(ctx_));
}

void GlContext::makeCurrent() {
  if (!OSMesaMakeCurrent(static_cast<OSMesaContext>(ctx_), dummy_, GL_UNSIGNED_BYTE, 4, 4))
    throw std::runtime_error("OSMesa: cannot make the context current");
}

std::string GlContext::description() {
  makeCurrent();
  const auto* r = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const auto* v = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  return std::string(r ? r : "?") + ", OpenGL " + (v ? v : "?");
}

namespace {

unsigned compileShader(const char* name, GLenum type, const std::string& src) {
  const GLuint s = glCreateShader(type);
  const char* p = src.c_str();
  glShaderSource(s, 1, &p, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    GLint len = 0;
    glGetShaderiv(s, GL_INFO_LOG_LENGTH, &len);
    std::vector<char> log(size_t(len) + 1, '\0');
    glGetShaderInfoLog(s, len, nullptr, log.data());
    glDeleteShader(s);
    throw std::runtime_error(std::string("preview shader '") + name + "' (" +
                             (type == GL_VERTEX_SHADER ? "vertex" : "fragment") +
                             ") does not compile: " + log.data());
  }
  return s;
}

}  // namespace

unsigned compileProgram(const char* name, const std::string& vertex, const std::string& fragment) {
  const GLuint vs = compileShader(name, GL_VERTEX_SHADER, vertex);
  const GLuint fs = compileShader(name, GL_FRAGMENT_SHADER, fragment);
  const GLuint prog = glCreateProgram();
  glAttachShader(prog, vs);
  glAttachShader(prog, fs);
  glLinkProgram(prog);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(prog, GL_LINK_STATUS, &ok);
  if (!ok) {
    GLint len = 0;
    glGetProgramiv(prog, GL_INFO_LOG_LENGTH, &len);
    std::vector<char> log(size_t(len) + 1, '\0');
    glGetProgramInfoLog(prog, len, nullptr, log.data());
    glDeleteProgram(prog);
    throw std::runtime_error(std::string("preview shader '") + name + "' does not link: " +
                             log.data());
  }
  return prog;
}

void checkGl(const char* where) {
  const GLenum e = glGetError();
  if (e != GL_NO_ERROR) {
    while (glGetError() != GL_NO_ERROR) {
    }
    throw std::runtime_error(std::string("OpenGL error ") + std::to_string(e) + " in " + where);
  }
}

}  // namespace triad::render
