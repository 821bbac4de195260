#pragma once
// An OpenGL 3.3 core context from OSMesa (Mesa's off-screen driver, llvmpipe): no window
// system, no display. Private to the render module.
//
// libOSMesa is opened with dlopen() rather than linked, so a machine without it still runs
// every other pneuma subcommand and rendering fails with one line saying what to install.
// GL entry points come from OSMesaGetProcAddress into a small table (the X-macro below lists
// every function the module uses), the way a GL loader such as glad does it, so nothing here
// depends on which library happens to export gl* symbols.
#include <GL/glcorearb.h>

#include <string>

namespace pneuma::render::detail {

// clang-format off
#define PNEUMA_GL_FUNCTIONS(X)                                                                  \
  X(PFNGLGETSTRINGPROC, GetString) X(PFNGLGETINTEGERVPROC, GetIntegerv)                        \
  X(PFNGLGETERRORPROC, GetError) X(PFNGLVIEWPORTPROC, Viewport) X(PFNGLCLEARCOLORPROC, ClearColor) \
  X(PFNGLCLEARPROC, Clear) X(PFNGLENABLEPROC, Enable) X(PFNGLDISABLEPROC, Disable)             \
  X(PFNGLCULLFACEPROC, CullFace) X(PFNGLDEPTHFUNCPROC, DepthFunc)                              \
  X(PFNGLREADPIXELSPROC, ReadPixels) X(PFNGLPIXELSTOREIPROC, PixelStorei) X(PFNGLREADBUFFERPROC, ReadBuffer) \
  X(PFNGLFINISHPROC, Finish)                                                                    \
  X(PFNGLGENFRAMEBUFFERSPROC, GenFramebuffers) X(PFNGLBINDFRAMEBUFFERPROC, BindFramebuffer)    \
  X(PFNGLDELETEFRAMEBUFFERSPROC, DeleteFramebuffers)                                            \
  X(PFNGLFRAMEBUFFERRENDERBUFFERPROC, FramebufferRenderbuffer)                                  \
  X(PFNGLCHECKFRAMEBUFFERSTATUSPROC, CheckFramebufferStatus)                                    \
  X(PFNGLGENRENDERBUFFERSPROC, GenRenderbuffers) X(PFNGLBINDRENDERBUFFERPROC, BindRenderbuffer) \
  X(PFNGLDELETERENDERBUFFERSPROC, DeleteRenderbuffers)                                          \
  X(PFNGLRENDERBUFFERSTORAGEPROC, RenderbufferStorage)                                          \
  X(PFNGLRENDERBUFFERSTORAGEMULTISAMPLEPROC, RenderbufferStorageMultisample)                    \
  X(PFNGLBLITFRAMEBUFFERPROC, BlitFramebuffer)                                                  \
  X(PFNGLCREATESHADERPROC, CreateShader) X(PFNGLSHADERSOURCEPROC, ShaderSource)                \
  X(PFNGLCOMPILESHADERPROC, CompileShader) X(PFNGLGETSHADERIVPROC, GetShaderiv)                \
  X(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog) X(PFNGLDELETESHADERPROC, DeleteShader)        \
  X(PFNGLCREATEPROGRAMPROC, CreateProgram) X(PFNGLATTACHSHADERPROC, AttachShader)              \
  X(PFNGLLINKPROGRAMPROC, LinkProgram) X(PFNGLGETPROGRAMIVPROC, GetProgramiv)                  \
  X(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog) X(PFNGLUSEPROGRAMPROC, UseProgram)          \
  X(PFNGLDELETEPROGRAMPROC, DeleteProgram) X(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation)  \
  X(PFNGLUNIFORM1FPROC, Uniform1f) X(PFNGLUNIFORM1IPROC, Uniform1i) X(PFNGLUNIFORM3FPROC, Uniform3f) \
  X(PFNGLUNIFORMMATRIX4FVPROC, UniformMatrix4fv)                                                \
  X(PFNGLGENVERTEXARRAYSPROC, GenVertexArrays) X(PFNGLBINDVERTEXARRAYPROC, BindVertexArray)    \
  X(PFNGLDELETEVERTEXARRAYSPROC, DeleteVertexArrays)                                            \
  X(PFNGLGENBUFFERSPROC, GenBuffers) X(PFNGLBINDBUFFERPROC, BindBuffer)                        \
  X(PFNGLBUFFERDATAPROC, BufferData) X(PFNGLDELETEBUFFERSPROC, DeleteBuffers)                  \
  X(PFNGLVERTEXATTRIBPOINTERPROC, VertexAttribPointer)                                          \
  X(PFNGLENABLEVERTEXATTRIBARRAYPROC, EnableVertexAttribArray)                                  \
  X(PFNGLDRAWELEMENTSPROC, DrawElements) X(PFNGLDRAWARRAYSPROC, DrawArrays)                    \
  X(PFNGLGENTEXTURESPROC, GenTextures) X(PFNGLBINDTEXTUREPROC, BindTexture)                    \
  X(PFNGLDELETETEXTURESPROC, DeleteTextures) X(PFNGLTEXIMAGE2DPROC, TexImage2D)                \
  X(PFNGLTEXPARAMETERIPROC, TexParameteri) X(PFNGLACTIVETEXTUREPROC, ActiveTexture)            \
  X(PFNGLFRAMEBUFFERTEXTURE2DPROC, FramebufferTexture2D) X(PFNGLUNIFORM2FPROC, Uniform2f)
// clang-format on

// The GL functions, called as gl.Clear(...) etc.
struct GlFunctions {
#define PNEUMA_GL_MEMBER(type, name) type name = nullptr;
  PNEUMA_GL_FUNCTIONS(PNEUMA_GL_MEMBER)
#undef PNEUMA_GL_MEMBER
};

// One OSMesa context. Not copyable; make_current() before any GL call on the calling thread
// (a context is current on one thread at a time).
class GlContext {
 public:
  // Throws UnsupportedError ("no OpenGL context: ...", naming the package to install) when
  // libOSMesa cannot be loaded or cannot give an OpenGL 3.3 core context.
  GlContext();
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  void make_current();
  const GlFunctions& gl() const { return gl_; }
  // "llvmpipe (LLVM 15.0.6, 256 bits)", "4.5 (Core Profile) Mesa 22.3.6".
  std::string renderer() const;
  std::string version() const;

 private:
  void* context_ = nullptr;
  // OSMesa needs a colour buffer to make a context current; everything is drawn into
  // framebuffer objects, so one pixel is enough.
  unsigned char dummy_buffer_[4] = {};
  GlFunctions gl_;
};

}  // namespace pneuma::render::detail
