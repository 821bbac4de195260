#pragma once
// An OpenGL core context (3.3 or newer: drivers give their highest, e.g. 4.5) without a window
// system or a display, from one of two backends. Private to the render module.
//   EGL: libEGL.so.1 (glvnd, with Mesa's or NVIDIA's vendor library), first a GPU through the
//     device platform (EGL_EXT_platform_device: NVIDIA, or Mesa on a DRM render node), then
//     Mesa's surfaceless platform (EGL_MESA_platform_surfaceless: a GPU or llvmpipe), then the
//     software device Mesa lists; no surface at all (EGL_KHR_surfaceless_context), everything
//     is drawn into framebuffer objects.
//   OSMesa: Mesa's off-screen driver (llvmpipe).
// automatic: EGL when it gives a context, else OSMesa.
//
// Both libraries are opened with dlopen() rather than linked, so a machine without them still
// runs every other pneuma subcommand and rendering fails with one line saying what to install.
// GL entry points come from the backend's GetProcAddress into a small table (the X-macro below
// lists every function the module uses), the way a GL loader such as glad does it, so nothing
// here depends on which library happens to export gl* symbols.
#include <GL/glcorearb.h>

#include <string>

#include "pneuma/render/renderer.h"

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
  X(PFNGLFRAMEBUFFERTEXTURE2DPROC, FramebufferTexture2D) X(PFNGLUNIFORM2FPROC, Uniform2f)    \
  X(PFNGLFLUSHPROC, Flush) X(PFNGLMAPBUFFERRANGEPROC, MapBufferRange)                        \
  X(PFNGLUNMAPBUFFERPROC, UnmapBuffer) X(PFNGLFENCESYNCPROC, FenceSync)                      \
  X(PFNGLCLIENTWAITSYNCPROC, ClientWaitSync) X(PFNGLDELETESYNCPROC, DeleteSync)
// clang-format on

// The GL functions, called as gl.Clear(...) etc.
struct GlFunctions {
#define PNEUMA_GL_MEMBER(type, name) type name = nullptr;
  PNEUMA_GL_FUNCTIONS(PNEUMA_GL_MEMBER)
#undef PNEUMA_GL_MEMBER
};

// One context. Not copyable; make_current() before any GL call on the calling thread (a context
// is current on one thread at a time).
class GlContext {
 public:
  // Throws UnsupportedError ("no OpenGL context: ...", naming the Debian packages to install)
  // when the backend asked for (or, for automatic, neither) gives an OpenGL 3.3+ core context.
  // automatic also honours PNEUMA_GL=egl|osmesa|auto in the environment.
  explicit GlContext(GlBackend backend = GlBackend::automatic);
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  void make_current();
  const GlFunctions& gl() const { return gl_; }
  // "llvmpipe (LLVM 15.0.6, 256 bits)", "4.5 (Core Profile) Mesa 22.3.6".
  std::string renderer() const;
  std::string version() const;
  // "EGL (device platform)", "EGL (surfaceless platform)", "EGL (software device)", "OSMesa".
  const std::string& backend() const { return backend_; }

 private:
  bool try_egl(std::string& why);
  void make_osmesa();
  std::string backend_;
  bool egl_ = false;
  void* egl_display_ = nullptr;
  void* context_ = nullptr;
  // OSMesa needs a colour buffer to make a context current; everything is drawn into
  // framebuffer objects, so one pixel is enough.
  unsigned char dummy_buffer_[4] = {};
  GlFunctions gl_;
};

}  // namespace pneuma::render::detail
