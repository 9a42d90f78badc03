#pragma once
// An off-screen OpenGL 3.3 core context through OSMesa (llvmpipe, no display),
// and the few GL object helpers the preview renderer needs. Only the .cpp
// files of render/ include GL headers.
#include <string>

namespace triad::render {

class GlContext {
 public:
  // Throws std::runtime_error when OSMesa cannot create a 3.3 core context.
  GlContext();
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  // Makes the context current on the calling thread (cheap; call per frame).
  void makeCurrent();
  // GL_RENDERER and GL_VERSION, for messages and benchmark records.
  std::string description();

 private:
  void* ctx_ = nullptr;
  unsigned char dummy_[4 * 4 * 4] = {};  // the default framebuffer is unused (we draw to an FBO)
};

// Compiles and links a program from vertex and fragment shader sources;
// throws std::runtime_error with the GL info log. Returns the program name.
unsigned compileProgram(const char* name, const std::string& vertex, const std::string& fragment);

// Throws std::runtime_error naming `where` when glGetError reports anything.
void checkGl(const char* where);

}  // namespace triad::render
