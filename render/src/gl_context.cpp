#include "gl_context.h"

#include <dlfcn.h>
#include <malloc.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <type_traits>
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
              kOsmesaProfile = 0x33, kOsmesaCoreProfile = 0x34, kOsmesaMajorVersion = 0x36, kOsmesaMinorVersion = 0x37;

const char* const kInstallHint = "install the libosmesa6 package (Mesa's off-screen OpenGL with llvmpipe)";
const char* const kEglInstallHint =
    "install the libegl1, libegl-mesa0 and libgl1-mesa-dri packages (EGL with Mesa; on NVIDIA the driver's EGL)";

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

// The EGL declarations used (EGL 1.5 and the extensions named in gl_context.h), so that
// building needs no EGL headers.
using EGLDisplay = void*;
using EGLConfig = void*;
using EGLContext = void*;
using EGLSurface = void*;
using EGLDeviceEXT = void*;
using EGLint = std::int32_t;
using EGLBoolean = unsigned int;
using EGLenum = unsigned int;
using EglProc = void (*)();
constexpr EGLint kEglNone = 0x3038, kEglExtensions = 0x3055, kEglRenderableType = 0x3040, kEglOpenglBit = 0x0008,
                 kEglSurfaceType = 0x3033, kEglPbufferBit = 0x0001, kEglContextMajorVersion = 0x3098,
                 kEglContextMinorVersion = 0x30FB, kEglContextOpenglProfileMask = 0x30FD,
                 kEglContextOpenglCoreProfileBit = 0x0001;
constexpr EGLenum kEglOpenglApi = 0x30A2, kEglPlatformDeviceExt = 0x313F, kEglPlatformSurfacelessMesa = 0x31DD;

struct Egl {
  std::string failure;  // empty when usable
  EglProc (*get_proc_address)(const char*) = nullptr;
  const char* (*query_string)(EGLDisplay, EGLint) = nullptr;
  EGLBoolean (*initialize)(EGLDisplay, EGLint*, EGLint*) = nullptr;
  EGLBoolean (*terminate)(EGLDisplay) = nullptr;
  EGLBoolean (*bind_api)(EGLenum) = nullptr;
  EGLBoolean (*choose_config)(EGLDisplay, const EGLint*, EGLConfig*, EGLint, EGLint*) = nullptr;
  EGLContext (*create_context)(EGLDisplay, EGLConfig, EGLContext, const EGLint*) = nullptr;
  EGLBoolean (*destroy_context)(EGLDisplay, EGLContext) = nullptr;
  EGLBoolean (*make_current)(EGLDisplay, EGLSurface, EGLSurface, EGLContext) = nullptr;
  EGLint (*get_error)() = nullptr;
  // Extensions (null when missing).
  EGLDisplay (*get_platform_display)(EGLenum, void*, const EGLint*) = nullptr;
  EGLBoolean (*query_devices)(EGLint, EGLDeviceEXT*, EGLint*) = nullptr;
  const char* (*query_device_string)(EGLDeviceEXT, EGLint) = nullptr;
};

bool has_extension(const char* list, const std::string& name) {
  if (!list) return false;
  const std::string all = std::string(" ") + list + " ";
  return all.find(" " + name + " ") != std::string::npos;
}

// Opens libEGL once per process (never closed). PNEUMA_EGL_LIBRARY names another file.
const Egl& egl() {
  static std::once_flag once;
  static Egl api;
  std::call_once(once, [] {
    keep_freed_memory();
    std::string name = "libEGL.so.1";
    if (const char* override_name = std::getenv("PNEUMA_EGL_LIBRARY"); override_name && *override_name) {
      name = override_name;
    }
    void* handle = ::dlopen(name.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      api.failure = "cannot load " + name;
      return;
    }
    const auto load = [&](auto& fn, const char* symbol) {
      fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(::dlsym(handle, symbol));
      if (!fn && api.failure.empty()) api.failure = name + " has no " + symbol;
    };
    load(api.get_proc_address, "eglGetProcAddress");
    load(api.query_string, "eglQueryString");
    load(api.initialize, "eglInitialize");
    load(api.terminate, "eglTerminate");
    load(api.bind_api, "eglBindAPI");
    load(api.choose_config, "eglChooseConfig");
    load(api.create_context, "eglCreateContext");
    load(api.destroy_context, "eglDestroyContext");
    load(api.make_current, "eglMakeCurrent");
    load(api.get_error, "eglGetError");
    if (!api.failure.empty()) return;
    const char* client = api.query_string(nullptr, kEglExtensions);  // EGL_EXT_client_extensions
    if (!has_extension(client, "EGL_EXT_platform_base")) {
      api.failure = name + " has no EGL_EXT_platform_base";
      return;
    }
    api.get_platform_display =
        reinterpret_cast<decltype(api.get_platform_display)>(api.get_proc_address("eglGetPlatformDisplayEXT"));
    if (has_extension(client, "EGL_EXT_device_enumeration") || has_extension(client, "EGL_EXT_device_base")) {
      api.query_devices = reinterpret_cast<decltype(api.query_devices)>(api.get_proc_address("eglQueryDevicesEXT"));
      api.query_device_string =
          reinterpret_cast<decltype(api.query_device_string)>(api.get_proc_address("eglQueryDeviceStringEXT"));
    }
    if (!has_extension(client, "EGL_EXT_platform_device")) api.query_devices = nullptr;
    if (!has_extension(client, "EGL_MESA_platform_surfaceless") && !api.query_devices) {
      api.failure = name + " offers neither EGL_EXT_platform_device nor EGL_MESA_platform_surfaceless";
    }
    if (!api.get_platform_display) api.failure = name + " has no eglGetPlatformDisplayEXT";
  });
  return api;
}

std::string egl_error_text(const Egl& api) {
  char buffer[16];
  std::snprintf(buffer, sizeof buffer, "0x%04x", static_cast<unsigned>(api.get_error()));
  return buffer;
}

GlBackend from_environment(GlBackend asked) {
  if (asked != GlBackend::automatic) return asked;
  if (const char* text = std::getenv("PNEUMA_GL"); text && *text) {
    GlBackend chosen;
    if (!parse_gl_backend(text, chosen)) {
      throw UsageError(std::string("render: PNEUMA_GL: expected egl, osmesa or auto, got '") + text + "'");
    }
    return chosen;
  }
  return asked;
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
std::string& osmesa_failure() {
  static std::string failure;
  return failure;
}

const OsMesa& osmesa() {
  static std::once_flag once;
  static OsMesa api;
  std::string& failure = osmesa_failure();
  std::call_once(once, [&failure] {
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

GlContext::GlContext(GlBackend backend) {
  backend = from_environment(backend);
  if (backend == GlBackend::osmesa) {
    make_osmesa();
    return;
  }
  std::string why;
  if (try_egl(why)) return;
  if (backend == GlBackend::egl) {
    throw UnsupportedError("render: no OpenGL context from EGL: " + why + "; " + kEglInstallHint);
  }
  try {
    make_osmesa();
  } catch (const UnsupportedError&) {
    const std::string osmesa_why = osmesa_failure().empty() ? "no context" : osmesa_failure();
    throw UnsupportedError("render: no OpenGL context: EGL: " + why + "; OSMesa: " + osmesa_why +
                           "; install the libegl1, libegl-mesa0 and libgl1-mesa-dri packages (or libosmesa6)");
  }
}

// One display tried after another; the first that gives a 3.3+ core context wins.
bool GlContext::try_egl(std::string& why) {
  const Egl& api = egl();
  if (!api.failure.empty()) {
    why = api.failure;
    return false;
  }
  struct Candidate {
    EGLenum platform;
    void* native;
    std::string name;
  };
  std::vector<Candidate> candidates, software;
  if (api.query_devices) {
    EGLDeviceEXT devices[16];
    EGLint count = 0;
    if (api.query_devices(16, devices, &count)) {
      for (EGLint i = 0; i < count; ++i) {
        const char* extensions =
            api.query_device_string ? api.query_device_string(devices[i], kEglExtensions) : nullptr;
        // Mesa lists llvmpipe as a device too; a GPU first, llvmpipe through surfaceless.
        if (has_extension(extensions, "EGL_MESA_device_software")) {
          software.push_back({kEglPlatformDeviceExt, devices[i], "EGL (software device)"});
        } else {
          candidates.push_back({kEglPlatformDeviceExt, devices[i], "EGL (device platform)"});
        }
      }
    }
  }
  if (has_extension(api.query_string(nullptr, kEglExtensions), "EGL_MESA_platform_surfaceless")) {
    candidates.push_back({kEglPlatformSurfacelessMesa, nullptr, "EGL (surfaceless platform)"});
  }
  candidates.insert(candidates.end(), software.begin(), software.end());
  why = "no EGL display";
  for (const Candidate& c : candidates) {
    EGLDisplay display = api.get_platform_display(c.platform, c.native, nullptr);
    if (!display) {
      why = c.name + ": no display (EGL error " + egl_error_text(api) + ")";
      continue;
    }
    EGLint major = 0, minor = 0;
    if (!api.initialize(display, &major, &minor)) {
      why = c.name + ": eglInitialize failed (EGL error " + egl_error_text(api) + ")";
      continue;
    }
    const char* extensions = api.query_string(display, kEglExtensions);
    if (!has_extension(extensions, "EGL_KHR_surfaceless_context") || !api.bind_api(kEglOpenglApi)) {
      why = c.name + ": no surfaceless OpenGL";
      api.terminate(display);
      continue;
    }
    EGLConfig config = nullptr;
    EGLint configs = 0;
    const EGLint config_attributes[] = {kEglRenderableType, kEglOpenglBit, kEglSurfaceType, kEglPbufferBit, kEglNone};
    if (!api.choose_config(display, config_attributes, &config, 1, &configs) || configs < 1) {
      config = nullptr;  // EGL_NO_CONFIG_KHR, where offered: the FBOs need no config
      if (!has_extension(extensions, "EGL_KHR_no_config_context")) {
        why = c.name + ": no OpenGL config";
        api.terminate(display);
        continue;
      }
    }
    const EGLint context_attributes[] = {
        kEglContextMajorVersion,         3,       kEglContextMinorVersion, 3, kEglContextOpenglProfileMask,
        kEglContextOpenglCoreProfileBit, kEglNone};
    EGLContext context = api.create_context(display, config, nullptr, context_attributes);
    if (!context) {
      why = c.name + ": no OpenGL 3.3 core context (EGL error " + egl_error_text(api) + ")";
      api.terminate(display);
      continue;
    }
    if (!api.make_current(display, nullptr, nullptr, context)) {
      why = c.name + ": eglMakeCurrent failed (EGL error " + egl_error_text(api) + ")";
      api.destroy_context(display, context);
      api.terminate(display);
      continue;
    }
    std::string missing;
#define PNEUMA_GL_LOAD(type, name)                                     \
  gl_.name = reinterpret_cast<type>(api.get_proc_address("gl" #name)); \
  if (!gl_.name && missing.empty()) missing = "gl" #name;
    PNEUMA_GL_FUNCTIONS(PNEUMA_GL_LOAD)
#undef PNEUMA_GL_LOAD
    if (!missing.empty()) {
      why = c.name + ": no " + missing;
      api.make_current(display, nullptr, nullptr, nullptr);
      api.destroy_context(display, context);
      api.terminate(display);
      gl_ = GlFunctions{};
      continue;
    }
    egl_ = true;
    egl_display_ = display;
    context_ = context;
    backend_ = c.name;
    return true;
  }
  return false;
}

void GlContext::make_osmesa() {
  const OsMesa& api = osmesa();
  backend_ = "OSMesa";
  const int attributes[] = {kOsmesaFormat,
                            kOsmesaRgba,
                            kOsmesaDepthBits,
                            0,
                            kOsmesaStencilBits,
                            0,
                            kOsmesaProfile,
                            kOsmesaCoreProfile,
                            kOsmesaMajorVersion,
                            3,
                            kOsmesaMinorVersion,
                            3,
                            0};
  context_ = api.create_context(attributes, nullptr);
  if (!context_) no_context(api.library + " could not create an OpenGL 3.3 core context");
  if (!api.make_current(context_, dummy_buffer_, GL_UNSIGNED_BYTE, 1, 1)) {
    api.destroy_context(context_);
    no_context(api.library + " could not make its context current");
  }
  bool complete = true;
  std::string missing;
#define PNEUMA_GL_LOAD(type, name)                                     \
  gl_.name = reinterpret_cast<type>(api.get_proc_address("gl" #name)); \
  if (!gl_.name && complete) {                                         \
    complete = false;                                                  \
    missing = "gl" #name;                                              \
  }
  PNEUMA_GL_FUNCTIONS(PNEUMA_GL_LOAD)
#undef PNEUMA_GL_LOAD
  if (!complete) {
    api.destroy_context(context_);
    no_context(api.library + " has no " + missing);
  }
}

GlContext::~GlContext() {
  if (!context_) return;
  if (egl_) {
    // The display stays initialised (EGL reference-counts nothing: terminating it would end
    // every other renderer's context on the same device).
    egl().make_current(egl_display_, nullptr, nullptr, nullptr);
    egl().destroy_context(egl_display_, context_);
  } else {
    osmesa().destroy_context(context_);
  }
}

void GlContext::make_current() {
  if (egl_) {
    if (!egl().make_current(egl_display_, nullptr, nullptr, context_)) {
      throw Error(ExitCode::failure, "render: eglMakeCurrent failed (EGL error " + egl_error_text(egl()) + ")");
    }
    return;
  }
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
