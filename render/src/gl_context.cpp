#include "gl_context.h"

#include <dlfcn.h>
#include <malloc.h>

#include <cstdlib>
#include <mutex>
#include <vector>

#include "pneuma/core/error.h"

namespace pneuma::render::detail {
namespace {

// The few OSMesa declarations used, from Mesa's GL/osmesa.h (which cannot be included next
// to glcorearb.h, as it pulls in the compatibility GL/gl.h).
using OSMesaContext = void*;
using OSMesaProc = void (*)();
using CreateContextAttribsFn = OSMesaContext (*)(const int* attributes, OSMesaContext share);
using MakeCurrentFn = GLboolean (*)(OSMesaContext, void* buffer, GLenum type, GLsizei width, GLsizei height);
using DestroyContextFn = void (*)(OSMesaContext);
using GetProcAddressFn = OSMesaProc (*)(const char* name);
constexpr int kOsmesaFormat = 0x22, kOsmesaRgba = GL_RGBA, kOsmesaDepthBits = 0x30, kOsmesaStencilBits = 0x31,
              kOsmesaProfile = 0x33, kOsmesaCoreProfile = 0x34, kOsmesaMajorVersion = 0x36,
              kOsmesaMinorVersion = 0x37;

const char* const kInstallHint = "install the libosmesa6 package (Mesa's off-screen OpenGL with llvmpipe)";

[[noreturn]] void no_context(const std::string& why) {
  throw UnsupportedError("render: no OpenGL context: " + why + "; " + kInstallHint);
}

// llvmpipe allocates and frees tens of megabytes per frame (scene bins, staging copies). With
// glibc's defaults those blocks come from fresh mmap()s and a 1280x720 frame costs ~10,000 page
// faults; measured, that doubles the CPU time of a frame. Keeping such blocks in the heap
// (process-wide: the allocator's thresholds; memory is reused, not returned to the system while
// under 256 MiB) removes the faults. PNEUMA_KEEP_MALLOC_DEFAULTS=1 leaves the allocator alone.
void keep_freed_memory() {
#ifdef __GLIBC__
  if (const char* keep = std::getenv("PNEUMA_KEEP_MALLOC_DEFAULTS"); keep && std::string(keep) == "1") return;
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
#endif
}

struct OsMesa {
  std::string library;
  CreateContextAttribsFn create_context = nullptr;
  MakeCurrentFn make_current = nullptr;
  DestroyContextFn destroy_context = nullptr;
  GetProcAddressFn get_proc_address = nullptr;
};

// Opens libOSMesa once per process (and never closes it: llvmpipe keeps threads alive).
// PNEUMA_OSMESA_LIBRARY names another library file (an unusual install, or a test).
const OsMesa& osmesa() {
  static std::once_flag once;
  static OsMesa api;
  static std::string failure;
  std::call_once(once, [] {
    keep_freed_memory();
    std::vector<std::string> names{"libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so"};
    if (const char* override_name = std::getenv("PNEUMA_OSMESA_LIBRARY"); override_name && *override_name) {
      names = {override_name};
    }
    void* handle = nullptr;
    for (const auto& name : names) {
      handle = ::dlopen(name.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (handle) {
        api.library = name;
        break;
      }
    }
    if (!handle) {
      failure = "cannot load " + names.front();
      return;
    }
    api.create_context = reinterpret_cast<CreateContextAttribsFn>(::dlsym(handle, "OSMesaCreateContextAttribs"));
    api.make_current = reinterpret_cast<MakeCurrentFn>(::dlsym(handle, "OSMesaMakeCurrent"));
    api.destroy_context = reinterpret_cast<DestroyContextFn>(::dlsym(handle, "OSMesaDestroyContext"));
    api.get_proc_address = reinterpret_cast<GetProcAddressFn>(::dlsym(handle, "OSMesaGetProcAddress"));
    if (!api.create_context || !api.make_current || !api.destroy_context || !api.get_proc_address) {
      failure = api.library + " lacks OSMesaCreateContextAttribs (Mesa 11.2 or newer is needed)";
    }
  });
  if (!failure.empty()) no_context(failure);
  return api;
}

}  // namespace

GlContext::GlContext() {
  const OsMesa& api = osmesa();
  const int attributes[] = {kOsmesaFormat,       kOsmesaRgba,        kOsmesaDepthBits,    0,
                            kOsmesaStencilBits,  0,                  kOsmesaProfile,      kOsmesaCoreProfile,
                            kOsmesaMajorVersion, 3,                  kOsmesaMinorVersion, 3,
                            0};
  context_ = api.create_context(attributes, nullptr);
  if (!context_) no_context(api.library + " could not create an OpenGL 3.3 core context");
  if (!api.make_current(context_, dummy_buffer_, GL_UNSIGNED_BYTE, 1, 1)) {
    api.destroy_context(context_);
    no_context(api.library + " could not make its context current");
  }
  bool complete = true;
  std::string missing;
#define PNEUMA_GL_LOAD(type, name)                                                     \
  gl_.name = reinterpret_cast<type>(api.get_proc_address("gl" #name));                 \
  if (!gl_.name && complete) {                                                          \
    complete = false;                                                                   \
    missing = "gl" #name;                                                               \
  }
  PNEUMA_GL_FUNCTIONS(PNEUMA_GL_LOAD)
#undef PNEUMA_GL_LOAD
  if (!complete) {
    api.destroy_context(context_);
    no_context(api.library + " has no " + missing);
  }
}

GlContext::~GlContext() {
  if (context_) osmesa().destroy_context(context_);
}

void GlContext::make_current() {
  if (!osmesa().make_current(context_, dummy_buffer_, GL_UNSIGNED_BYTE, 1, 1)) {
    throw Error(ExitCode::failure, "render: OSMesaMakeCurrent failed");
  }
}

std::string GlContext::renderer() const {
  const auto* text = gl_.GetString(GL_RENDERER);
  return text ? reinterpret_cast<const char*>(text) : "";
}

std::string GlContext::version() const {
  const auto* text = gl_.GetString(GL_VERSION);
  return text ? reinterpret_cast<const char*>(text) : "";
}

}  // namespace pneuma::render::detail
