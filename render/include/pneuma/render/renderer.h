#pragma once
// Headless renderer of a breathing lung: frame(s) = rest + s * u, displaced in the vertex shader.
//
// Built once, queried per frame (like a solver object): the constructor creates an OpenGL 3.3
// core context with OSMesa, uploads the rest positions, the field u and the normal terms as
// vertex attributes, and frames the camera on the bounds of the mesh over the range of s.
// render(s) then only sets the uniform `s`, draws, resolves the multisampled image and reads it
// back: no upload, no allocation when the caller reuses the output image.
//
//   render::Renderer renderer(rest, field, max_scale, options);
//   for (...) render::write_png(dir / name, renderer.render(s));
//
// Normals follow the deformation exactly. The area-weighted vertex normal of rest + s u (the
// same one mesh::vertex_normals computes) is, before normalisation, the sum of the incident
// triangles' cross products (b - a) x (c - a), each quadratic in s:
//   m_i(s) = n0_i + s n1_i + s^2 n2_i
// The three coefficients are precomputed per vertex and the shader normalises m_i(s).
//
// Not thread-safe: use one renderer from one thread at a time (each call makes its context
// current on the calling thread).
#include <Eigen/Core>
#include <array>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/render/camera.h"
#include "pneuma/render/image.h"

namespace pneuma::render {

// Where the OpenGL context comes from (see BENCHMARKS.md, Render): EGL (a GPU through the device
// platform, or Mesa's surfaceless platform: a GPU or llvmpipe), or OSMesa (llvmpipe). automatic:
// EGL when it gives a context, else OSMesa; the environment variable PNEUMA_GL=egl|osmesa|auto
// overrides automatic (so every renderer of a run, e.g. the PNG output, can be pointed at one).
enum class GlBackend { automatic, egl, osmesa };
// "auto", "egl", "osmesa"; false for anything else.
bool parse_gl_backend(const std::string& text, GlBackend& out);

// Colours are sRGB, 0..1; lighting is computed in linear light.
struct Material {
  Eigen::Vector3d base_colour = {0.87, 0.56, 0.56};  // healthy lung: pink
  double specular = 0.22;                            // soft, wet-looking highlight
  double shininess = 24.0;
  double wrap = 0.35;  // diffuse wrap-around (0 = Lambert): softens the terminator like tissue
  double rim = 0.18;   // faint light at grazing angles (the pleura's sheen)
};

struct RenderOptions {
  int width = 640;  // pixels
  int height = 480;
  CameraPreset camera = CameraPreset::anterior;
  double fov_y_deg = 30.0;
  double margin = 1.1;  // free space around the framed bounds
  // Anti-aliasing. MSAA samples the geometry (best edges; on llvmpipe its cost grows with the
  // triangle count: about 3x the frame time at 1.3M triangles, see BENCHMARKS.md); FXAA
  // (Lottes) smooths edges in one pass over the image at a fixed cost per pixel, the choice for
  // dense meshes. Both may be on; msaa_samples 0 or 1 turns MSAA off (clamped to the driver's
  // limit).
  int msaa_samples = 4;
  bool fxaa = false;
  Eigen::Vector3d background = {0.11, 0.12, 0.15};  // sRGB
  Material material;
  bool cull_back_faces = true;  // lung surfaces are closed and outward-oriented
  // Overlay: colour by the displacement magnitude |s u| (viridis), with a colour bar legend.
  bool overlay_magnitude = false;
  double overlay_max_m = 0.0;  // top of the colour scale; 0: max |u| * max |s| of the range (fixed across frames)
  bool legend = true;          // the colour bar (drawn only with the overlay)
  GlBackend gl = GlBackend::automatic;
};
inline const RenderOptions default_render_options{};

// The values of s a run renders (RunInfo's min_scale and max_scale): the camera frames every
// frame in the range, and the overlay's colour scale reaches the largest |s| u.
struct ScaleRange {
  double min = 0.0;
  double max = 1.0;
};

// One surface of a scene (two lungs: two), moved by its own s over its own range of scales.
struct RenderPart {
  const mesh::TriangleMesh* rest = nullptr;
  const std::vector<Eigen::Vector3d>* field = nullptr;  // one vector per vertex of *rest
  ScaleRange scales;
};

class Renderer {
 public:
  // Several surfaces in one image (the arguments are copied to the GPU; they may go afterwards):
  // the camera frames all of them over their ranges; each frame gives each surface its own s.
  // Throws as the one-surface constructor, and ValueError for no surface.
  Renderer(std::span<const RenderPart> surfaces, const RenderOptions& options = default_render_options);
  // `field` has one vector per vertex of `rest` (metres per unit of s). The camera frames the
  // bounds of rest + s u over s in `scales` (and rest itself), so it does not move between
  // frames. Throws UnsupportedError when no OpenGL context can be created (the message says
  // what to install) or the image is larger than the driver allows, InputError when the field
  // or the triangles do not fit the mesh, UsageError for a non-positive image size.
  Renderer(const mesh::TriangleMesh& rest, const std::vector<Eigen::Vector3d>& field, ScaleRange scales,
           const RenderOptions& options = default_render_options);
  // Frames s in [0, max_scale].
  Renderer(const mesh::TriangleMesh& rest, const std::vector<Eigen::Vector3d>& field, double max_scale,
           const RenderOptions& options = default_render_options)
      : Renderer(rest, field, ScaleRange{0.0, max_scale}, options) {}
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // The frame at scale s (s = 0 is the rest mesh).
  Image render(double s);
  // Same, into `out` (resized once, then reused: the per-frame path allocates nothing).
  void render(double s, Image& out);
  // The frame with surface i at scale s[i] (one per surface). Throws ValueError for a wrong count.
  Image render(std::span<const double> s);
  void render(std::span<const double> s, Image& out);

  // Pipelined frames, for sequences: submit() draws a frame and starts reading it back without
  // waiting; collect() waits for the oldest frame submitted and copies it into `out`. With two
  // in flight, the GPU draws one frame while the previous one comes back to memory. Frames come
  // back in the order submitted, each the image render() gives for its s. render() needs none in
  // flight. Throws as render(), and Error(failure) when submitting a third or collecting none.
  static constexpr std::size_t max_frames_in_flight = 2;
  void submit(std::span<const double> s);
  void submit(double s);
  void collect(Image& out);
  std::size_t frames_in_flight() const;

  // Per-frame view changes (no re-upload).
  void set_camera(CameraPreset preset);  // framed on the same bounds as at construction
  void set_camera(const Camera& camera);
  const Camera& camera() const;
  const RenderOptions& options() const;
  // The bounds the camera frames: those of rest and rest + s u at both ends of the range.
  const std::array<Eigen::Vector3d, 2>& framed_bounds() const;
  // The overlay's top value (m).
  double overlay_max_m() const;
  // The OpenGL renderer and version strings, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
  std::string gl_renderer() const;
  std::string gl_version() const;
  std::string gl_backend() const;  // "EGL (surfaceless platform)", "OSMesa", ...
  int msaa_samples() const;        // after clamping
  // The triangles handed to OpenGL for a frame at s (every surface at s): with back-face culling, those that face away
  // from the camera at every s of the range are left out (the image is the same).
  std::size_t drawn_triangles(double s) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The precomputed normal terms (see above), per vertex: {n0, n1, n2}, scaled by 1 / |n0| so
// the values stay near unit length (the direction of the sum is unchanged). Public for tests.
struct NormalTerms {
  std::vector<Eigen::Vector3d> n0, n1, n2;
};
NormalTerms normal_terms(const mesh::TriangleMesh& rest, const std::vector<Eigen::Vector3d>& field);

}  // namespace pneuma::render
