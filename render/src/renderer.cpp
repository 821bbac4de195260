#include "pneuma/render/renderer.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <span>
#include <string>

#include "gl_context.h"
#include "overlay.h"
#include "pneuma/core/error.h"

namespace pneuma::render {

NormalTerms normal_terms(const mesh::TriangleMesh& rest, const std::vector<Eigen::Vector3d>& field) {
  const std::size_t n = rest.vertex_count();
  NormalTerms t{std::vector<Eigen::Vector3d>(n, Eigen::Vector3d::Zero()),
                std::vector<Eigen::Vector3d>(n, Eigen::Vector3d::Zero()),
                std::vector<Eigen::Vector3d>(n, Eigen::Vector3d::Zero())};
  for (const mesh::Triangle& tri : rest.triangles) {
    const Eigen::Vector3d& a = rest.vertices[tri[0]];
    const Eigen::Vector3d e1 = rest.vertices[tri[1]] - a, e2 = rest.vertices[tri[2]] - a;
    const Eigen::Vector3d f1 = field[tri[1]] - field[tri[0]], f2 = field[tri[2]] - field[tri[0]];
    // (e1 + s f1) x (e2 + s f2) = e1 x e2 + s (e1 x f2 + f1 x e2) + s^2 f1 x f2
    const Eigen::Vector3d c0 = e1.cross(e2), c1 = e1.cross(f2) + f1.cross(e2), c2 = f1.cross(f2);
    for (std::uint32_t v : tri) {
      t.n0[v] += c0;
      t.n1[v] += c1;
      t.n2[v] += c2;
    }
  }
  for (std::size_t v = 0; v < n; ++v) {
    const double length = t.n0[v].norm();
    if (length > 0.0) {
      t.n0[v] /= length;
      t.n1[v] /= length;
      t.n2[v] /= length;
    }
  }
  return t;
}

namespace {

// The frame x = rest + s u is computed here, per vertex, from attributes uploaded once. On
// llvmpipe the vertex stage and the per-triangle set-up of every varying run on the calling
// thread, the part of a frame that no core count shortens, so the shaders pass as few varyings
// as they can: the view direction comes from gl_FragCoord (exact under a perspective camera),
// and the displacement magnitude only when the overlay shows it (OVERLAY, defined by
// shader_prelude()).
constexpr const char* kVertexShader = R"(
layout(location = 0) in vec3 rest;
layout(location = 1) in vec3 field;
layout(location = 2) in vec3 normal0;
layout(location = 3) in vec3 normal1;
layout(location = 4) in vec3 normal2;
uniform float s;
uniform mat4 view_from_model;  // rigid: rotation and translation only
uniform mat4 clip_from_view;
out vec3 view_normal;
#ifdef OVERLAY
out float magnitude;
#endif
void main() {
  vec3 position = rest + s * field;
  vec3 normal = normal0 + s * (normal1 + s * normal2);  // area-weighted normal of the frame
  view_normal = mat3(view_from_model) * normal;
#ifdef OVERLAY
  magnitude = abs(s) * length(field);
#endif
  gl_Position = clip_from_view * (view_from_model * vec4(position, 1.0));
}
)";

std::string shader_prelude(bool overlay) {
  return overlay ? "#version 330 core\n#define OVERLAY 1\n" : "#version 330 core\n";
}

// Lighting in linear light, written out as sRGB. Two lights fixed to the camera (a key light
// above and left, a weaker fill from the right), wrapped diffuse for a soft tissue look, a
// broad Blinn-Phong highlight, a faint rim.
constexpr const char* kFragmentShaderHead = R"(
in vec3 view_normal;
#ifdef OVERLAY
in float magnitude;
uniform float overlay_max;
#endif
uniform vec3 base_colour;
uniform float specular;
uniform float shininess;
uniform float wrap;
uniform float rim;
// The view ray through a pixel: (ray_scale * gl_FragCoord.xy + ray_offset, -1) in view space.
uniform vec2 ray_scale;
uniform vec2 ray_offset;
out vec4 colour;
)";
constexpr const char* kFragmentShaderBody = R"(
vec3 to_linear(vec3 c) { return pow(c, vec3(2.2)); }
vec3 to_srgb(vec3 c) { return pow(clamp(c, 0.0, 1.0), vec3(1.0 / 2.2)); }
void main() {
  vec3 n = normalize(view_normal);
  if (!gl_FrontFacing) n = -n;
  vec3 v = normalize(vec3(-(ray_scale * gl_FragCoord.xy + ray_offset), 1.0));  // towards the eye
#ifdef OVERLAY
  vec3 albedo = to_linear(viridis_srgb(magnitude / overlay_max));
  colour = vec4(to_srgb(albedo * (0.55 + 0.45 * max(dot(n, v), 0.0))), 1.0);
#else
  vec3 albedo = to_linear(base_colour);
  const vec3 key = normalize(vec3(-0.45, 0.6, 0.65));
  const vec3 fill = normalize(vec3(0.7, -0.15, 0.7));
  float key_diffuse = max((dot(n, key) + wrap) / (1.0 + wrap), 0.0);
  float fill_diffuse = max((dot(n, fill) + wrap) / (1.0 + wrap), 0.0);
  vec3 h = normalize(key + v);
  float highlight = dot(n, key) > 0.0 ? specular * pow(max(dot(n, h), 0.0), shininess) : 0.0;
  float sheen = rim * pow(1.0 - max(dot(n, v), 0.0), 3.0);
  vec3 lit = albedo * (0.06 + 0.85 * key_diffuse + 0.25 * fill_diffuse) + vec3(highlight) + sheen * vec3(1.0, 0.9, 0.9);
  colour = vec4(to_srgb(lit), 1.0);
#endif
}
)";

// FXAA, after T. Lottes, "FXAA" (NVIDIA white paper, 2009), in its compact form: pixels whose
// neighbourhood has little luma contrast are kept as they are (most of the image: smooth
// shading, background); elsewhere the luma gradient gives the edge direction, two or four
// bilinear taps along it blend the edge, and the wider blend is used only when its luma stays
// in the neighbourhood's range.
// A full-screen triangle made from gl_VertexID (no vertex buffer).
constexpr const char* kFullScreenVertexShader = R"(#version 330 core
void main() {
  vec2 corner = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(corner * 2.0 - 1.0, 0.0, 1.0);
}
)";
constexpr const char* kFxaaFragmentShader = R"(#version 330 core
uniform sampler2D scene;
uniform vec2 texel;  // 1 / image size
out vec4 colour;
const float reduce_min = 1.0 / 128.0, reduce_mul = 1.0 / 8.0, span_max = 8.0;
float luma(vec3 c) { return dot(c, vec3(0.299, 0.587, 0.114)); }
vec3 at(ivec2 p, ivec2 offset) {
  return texelFetch(scene, clamp(p + offset, ivec2(0), textureSize(scene, 0) - 1), 0).rgb;
}
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec3 centre = texelFetch(scene, p, 0).rgb;
  float m = luma(centre);
  float nw = luma(at(p, ivec2(-1, -1))), ne = luma(at(p, ivec2(1, -1)));
  float sw = luma(at(p, ivec2(-1, 1))), se = luma(at(p, ivec2(1, 1)));
  float lo = min(m, min(min(nw, ne), min(sw, se)));
  float hi = max(m, max(max(nw, ne), max(sw, se)));
  // No edge here (smooth shading or background): keep the pixel, skip the filter's taps.
  if (hi - lo < max(1.0 / 24.0, hi / 8.0)) {
    colour = vec4(centre, 1.0);
    return;
  }
  vec2 uv = gl_FragCoord.xy * texel;
  vec2 dir = vec2(-((nw + ne) - (sw + se)), (nw + sw) - (ne + se));
  float reduce = max((nw + ne + sw + se) * 0.25 * reduce_mul, reduce_min);
  dir = clamp(dir / (min(abs(dir.x), abs(dir.y)) + reduce), vec2(-span_max), vec2(span_max)) * texel;
  vec3 a = 0.5 * (texture(scene, uv + dir * (1.0 / 3.0 - 0.5)).rgb + texture(scene, uv + dir * (2.0 / 3.0 - 0.5)).rgb);
  vec3 b = 0.5 * a + 0.25 * (texture(scene, uv - 0.5 * dir).rgb + texture(scene, uv + 0.5 * dir).rgb);
  float lb = luma(b);
  colour = vec4((lb < lo || lb > hi) ? a : b, 1.0);
}
)";

// The vertex layout: 15 floats, positions relative to `origin` (the centre of the framed
// bounds) so single precision keeps sub-micrometre resolution whatever the mesh's placement.
struct Vertex {
  float rest[3];
  float field[3];
  float normal0[3];
  float normal1[3];
  float normal2[3];
};
static_assert(sizeof(Vertex) == 15 * sizeof(float));

void put(float (&out)[3], const Eigen::Vector3d& v) {
  out[0] = static_cast<float>(v.x());
  out[1] = static_cast<float>(v.y());
  out[2] = static_cast<float>(v.z());
}

std::array<Eigen::Vector3d, 2> bounds_over_range(const mesh::TriangleMesh& rest,
                                                 const std::vector<Eigen::Vector3d>& field, ScaleRange scales) {
  // Every point of rest + s u for s in [min, max] lies between its two end points, so the box
  // of the two end frames holds all frames in between.
  auto box = mesh::bounding_box(rest.vertices);
  for (std::size_t i = 0; i < rest.vertices.size(); ++i) {
    for (double s : {scales.min, scales.max}) {
      const Eigen::Vector3d p = rest.vertices[i] + s * field[i];
      box[0] = box[0].cwiseMin(p);
      box[1] = box[1].cwiseMax(p);
    }
  }
  return box;
}

// Spreads the low 10 bits of v to every third bit (for a 30-bit Morton code).
std::uint32_t spread_bits(std::uint32_t v) {
  v &= 0x3ffu;
  v = (v | (v << 16)) & 0x030000ffu;
  v = (v | (v << 8)) & 0x0300f00fu;
  v = (v | (v << 4)) & 0x030c30c3u;
  v = (v | (v << 2)) & 0x09249249u;
  return v;
}

// The draw order. llvmpipe's draw module fetches and shades vertices in batches, reusing a
// vertex only when it is still in a small direct-mapped cache (slot = index % 256), so triangles
// that share vertices should be near each other in the index buffer. Meshes come in any order
// (a remesher's output may be far from coherent: a shuffled 1.3M-triangle icosphere drew 3.5x
// slower than the ordered one). So the triangles are also sorted along a Morton (Z-order) curve
// of their centroids, vertices are numbered by first use in both orders, and the order that
// misses that cache least is uploaded (ties keep the input order). Only the order changes, not
// the image.
struct DrawOrder {
  std::vector<mesh::Triangle> triangles;     // in new vertex numbers
  std::vector<std::uint32_t> source_vertex;  // new number -> rest vertex
  std::size_t cache_misses = 0;
};

DrawOrder renumbered(const mesh::TriangleMesh& rest, const std::vector<std::uint32_t>& triangle_order) {
  constexpr std::uint32_t unused = std::numeric_limits<std::uint32_t>::max();
  DrawOrder order;
  std::vector<std::uint32_t> new_number(rest.vertex_count(), unused);
  order.source_vertex.reserve(rest.vertex_count());
  order.triangles.reserve(triangle_order.size());
  std::array<std::uint32_t, 256> cache;
  cache.fill(unused);
  for (std::uint32_t t : triangle_order) {
    mesh::Triangle tri = rest.triangles[t];
    for (std::uint32_t& v : tri) {
      if (new_number[v] == unused) {
        new_number[v] = static_cast<std::uint32_t>(order.source_vertex.size());
        order.source_vertex.push_back(v);
      }
      v = new_number[v];
      if (cache[v % 256] != v) {
        cache[v % 256] = v;
        ++order.cache_misses;
      }
    }
    order.triangles.push_back(tri);
  }
  return order;  // vertices no triangle uses are left out: they are never drawn
}

DrawOrder draw_order(const mesh::TriangleMesh& rest) {
  const std::size_t n = rest.triangle_count();
  std::vector<std::uint32_t> input(n);
  for (std::size_t t = 0; t < n; ++t) input[t] = static_cast<std::uint32_t>(t);
  DrawOrder as_given = renumbered(rest, input);
  if (n == 0) return as_given;
  const auto [lo, hi] = mesh::bounding_box(rest.vertices);
  const Eigen::Vector3d extent = (hi - lo).cwiseMax(1e-12);
  std::vector<std::pair<std::uint32_t, std::uint32_t>> keyed(n);  // (Morton code, triangle)
  for (std::size_t t = 0; t < n; ++t) {
    const auto& tri = rest.triangles[t];
    const Eigen::Vector3d centroid = (rest.vertices[tri[0]] + rest.vertices[tri[1]] + rest.vertices[tri[2]]) / 3.0;
    const Eigen::Vector3d unit = (centroid - lo).cwiseQuotient(extent);
    auto cell = [](double x) { return static_cast<std::uint32_t>(std::clamp(x, 0.0, 1.0) * 1023.0); };
    keyed[t] = {spread_bits(cell(unit.x())) | (spread_bits(cell(unit.y())) << 1) | (spread_bits(cell(unit.z())) << 2),
                static_cast<std::uint32_t>(t)};
  }
  std::sort(keyed.begin(), keyed.end());
  for (std::size_t t = 0; t < n; ++t) input[t] = keyed[t].second;
  DrawOrder morton = renumbered(rest, input);
  return morton.cache_misses < as_given.cache_misses ? std::move(morton) : std::move(as_given);
}

// Whether a triangle faces away from the eye at every scale s in [s_min, s_max], with a margin,
// so that OpenGL's back-face culling would drop it in every frame of the range. The camera is
// fixed while a run draws, and llvmpipe shades the vertices, assembles and culls every
// triangle it is given on the calling thread (the part of a frame no core count shortens), so
// such triangles are left out of the draw: the image is the same, bit for bit, since a culled
// triangle writes nothing and the others keep their order.
// With p the first corner and N = (b - a) x (c - a) both moving with s (p + s u, N0 + s N1 +
// s^2 N2), the triangle faces away where g(s) = (p(s) - eye) . N(s) > 0, a cubic in s whose
// minimum over the range is at an end or where g' = 0. It is dropped only where that minimum
// exceeds 1 % of |p - eye| |N| (about 0.6 degrees from edge-on: no float rounding in OpenGL's
// own test can flip it) and every corner stays in front of the eye (no clipping).
bool faces_away_throughout(const std::array<Eigen::Vector3d, 3>& p, const std::array<Eigen::Vector3d, 3>& u,
                           const Eigen::Vector3d& eye, const Eigen::Vector3d& forward, double near_m, ScaleRange s) {
  for (int k = 0; k < 3; ++k) {
    for (double end : {s.min, s.max}) {
      if ((p[k] + end * u[k] - eye).dot(forward) <= near_m) return false;
    }
  }
  const Eigen::Vector3d e1 = p[1] - p[0], e2 = p[2] - p[0], f1 = u[1] - u[0], f2 = u[2] - u[0];
  const Eigen::Vector3d n0 = e1.cross(e2), n1 = e1.cross(f2) + f1.cross(e2), n2 = f1.cross(f2);
  const Eigen::Vector3d a0 = p[0] - eye;
  const Eigen::Vector3d& a1 = u[0];
  const double c0 = a0.dot(n0), c1 = a0.dot(n1) + a1.dot(n0), c2 = a0.dot(n2) + a1.dot(n1), c3 = a1.dot(n2);
  auto g = [&](double x) { return c0 + x * (c1 + x * (c2 + x * c3)); };
  double lowest = std::min(g(s.min), g(s.max));
  // g'(x) = c1 + 2 c2 x + 3 c3 x^2
  const double qa = 3.0 * c3, qb = 2.0 * c2, qc = c1;
  auto consider = [&](double x) {
    if (x > s.min && x < s.max) lowest = std::min(lowest, g(x));
  };
  if (qa != 0.0) {
    const double disc = qb * qb - 4.0 * qa * qc;
    if (disc >= 0.0) {
      const double root = std::sqrt(disc);
      consider((-qb - root) / (2.0 * qa));
      consider((-qb + root) / (2.0 * qa));
    }
  } else if (qb != 0.0) {
    consider(-qc / qb);
  }
  const double reach = std::max(std::abs(s.min), std::abs(s.max));
  const double scale = (a0.norm() + reach * a1.norm()) * (n0.norm() + reach * (n1.norm() + reach * n2.norm()));
  return lowest > 0.01 * scale;
}

}  // namespace

struct Renderer::Impl {
  explicit Impl(GlBackend backend) : context(backend) {}
  detail::GlContext context;
  RenderOptions options;
  std::array<Eigen::Vector3d, 2> bounds;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Camera camera;
  double overlay_max = 0.0;
  int samples = 0;
  GLsizei index_count = 0;
  // The triangles (in draw order and vertex numbers) and, for the pre-cull, each vertex's rest
  // position relative to `origin` and field; the scales the pre-cull holds for, and the
  // triangles that may face the camera somewhere in that range (visible_buffer).
  std::vector<mesh::Triangle> draw_triangles;
  std::vector<Eigen::Vector3f> draw_rest, draw_field;
  GLsizei visible_index_count = 0;
  // The surfaces drawn (two lungs: two), each its own range of the index buffer (and of the
  // visible buffer), moved by its own s over its own range of scales.
  struct Part {
    ScaleRange scales;
    GLsizei index_begin = 0, index_count = 0;
    GLsizei visible_begin = 0, visible_count = 0;
  };
  std::vector<Part> parts;
  bool precull = false;

  GLuint program = 0, vao = 0, vertex_buffer = 0, index_buffer = 0, visible_buffer = 0;
  // Geometry is drawn into msaa_fbo (multisampled renderbuffers) and resolved into image_fbo,
  // or drawn into image_fbo directly without MSAA; with FXAA a full-screen pass filters
  // image_fbo's texture into output_fbo. The last of these is read back.
  GLuint msaa_fbo = 0, image_fbo = 0, output_fbo = 0;
  GLuint msaa_colour_rb = 0, msaa_depth_rb = 0, depth_rb = 0, output_rb = 0, image_texture = 0;
  GLuint fxaa_program = 0, empty_vao = 0;
  GLint s_location = -1, view_location = -1, projection_location = -1, ray_scale_location = -1,
        ray_offset_location = -1;
  // The read-back ring: each slot a pixel-pack buffer and the fence of the frame read into it;
  // slots in flight are oldest, oldest + 1, ... (mod the ring's size).
  struct Readback {
    GLuint buffer = 0;
    GLsync fence = nullptr;
  };
  std::array<Readback, Renderer::max_frames_in_flight> readbacks;
  std::size_t oldest = 0, in_flight = 0;

  const detail::GlFunctions& gl() const { return context.gl(); }

  GLuint compile(GLenum type, const std::string& source) {
    const GLuint shader = gl().CreateShader(type);
    const char* text = source.c_str();
    gl().ShaderSource(shader, 1, &text, nullptr);
    gl().CompileShader(shader);
    GLint ok = 0;
    gl().GetShaderiv(shader, GL_COMPILE_STATUS, &ok);
    if (!ok) {
      char log[2048] = {};
      gl().GetShaderInfoLog(shader, sizeof log, nullptr, log);
      gl().DeleteShader(shader);
      throw Error(ExitCode::failure, std::string("render: shader does not compile: ") + log);
    }
    return shader;
  }

  GLuint link(const std::string& vertex_source, const std::string& fragment_source) {
    const GLuint vs = compile(GL_VERTEX_SHADER, vertex_source);
    const GLuint fs = compile(GL_FRAGMENT_SHADER, fragment_source);
    const GLuint linked = gl().CreateProgram();
    gl().AttachShader(linked, vs);
    gl().AttachShader(linked, fs);
    gl().LinkProgram(linked);
    gl().DeleteShader(vs);
    gl().DeleteShader(fs);
    GLint ok = 0;
    gl().GetProgramiv(linked, GL_LINK_STATUS, &ok);
    if (!ok) {
      char log[2048] = {};
      gl().GetProgramInfoLog(linked, sizeof log, nullptr, log);
      gl().DeleteProgram(linked);
      throw Error(ExitCode::failure, std::string("render: shaders do not link: ") + log);
    }
    return linked;
  }

  void build_fxaa() {
    fxaa_program = link(kFullScreenVertexShader, kFxaaFragmentShader);
    gl().UseProgram(fxaa_program);
    gl().Uniform1i(gl().GetUniformLocation(fxaa_program, "scene"), 0);
    gl().Uniform2f(gl().GetUniformLocation(fxaa_program, "texel"), 1.0f / static_cast<float>(options.width),
                   1.0f / static_cast<float>(options.height));
    gl().GenVertexArrays(1, &empty_vao);  // core profile: a draw needs a vertex array object
  }

  void build_program() {
    const bool overlay = options.overlay_magnitude;
    program = link(shader_prelude(overlay) + kVertexShader,
                   shader_prelude(overlay) + kFragmentShaderHead + detail::viridis_glsl() + kFragmentShaderBody);
    s_location = gl().GetUniformLocation(program, "s");
    view_location = gl().GetUniformLocation(program, "view_from_model");
    projection_location = gl().GetUniformLocation(program, "clip_from_view");
    ray_scale_location = gl().GetUniformLocation(program, "ray_scale");
    ray_offset_location = gl().GetUniformLocation(program, "ray_offset");
    gl().UseProgram(program);
    const Material& m = options.material;
    gl().Uniform3f(gl().GetUniformLocation(program, "base_colour"), static_cast<float>(m.base_colour.x()),
                   static_cast<float>(m.base_colour.y()), static_cast<float>(m.base_colour.z()));
    gl().Uniform1f(gl().GetUniformLocation(program, "specular"), static_cast<float>(m.specular));
    gl().Uniform1f(gl().GetUniformLocation(program, "shininess"), static_cast<float>(m.shininess));
    gl().Uniform1f(gl().GetUniformLocation(program, "wrap"), static_cast<float>(m.wrap));
    gl().Uniform1f(gl().GetUniformLocation(program, "rim"), static_cast<float>(m.rim));
    if (overlay) gl().Uniform1f(gl().GetUniformLocation(program, "overlay_max"), static_cast<float>(overlay_max));
  }

  // Every part's vertices and triangles, one after the other, each part in its own draw order.
  void upload(std::span<const RenderPart> surfaces) {
    std::vector<Vertex> vertices;
    DrawOrder order;
    for (std::size_t p = 0; p < surfaces.size(); ++p) {
      const mesh::TriangleMesh& rest = *surfaces[p].rest;
      const std::vector<Eigen::Vector3d>& field = *surfaces[p].field;
      const NormalTerms normals = normal_terms(rest, field);
      const DrawOrder part = draw_order(rest);
      const std::size_t first = vertices.size();
      vertices.resize(first + part.source_vertex.size());
      for (std::size_t k = 0; k < part.source_vertex.size(); ++k) {
        const std::uint32_t i = part.source_vertex[k];
        Vertex& v = vertices[first + k];
        put(v.rest, rest.vertices[i] - origin);
        put(v.field, field[i]);
        put(v.normal0, normals.n0[i]);
        put(v.normal1, normals.n1[i]);
        put(v.normal2, normals.n2[i]);
      }
      parts[p].index_begin = static_cast<GLsizei>(order.triangles.size() * 3);
      parts[p].index_count = static_cast<GLsizei>(part.triangles.size() * 3);
      for (mesh::Triangle t : part.triangles) {
        for (std::uint32_t& v : t) v += static_cast<std::uint32_t>(first);
        order.triangles.push_back(t);
      }
    }
    gl().GenVertexArrays(1, &vao);
    gl().BindVertexArray(vao);
    gl().GenBuffers(1, &vertex_buffer);
    gl().BindBuffer(GL_ARRAY_BUFFER, vertex_buffer);
    gl().BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(vertices.size() * sizeof(Vertex)), vertices.data(),
                    GL_STATIC_DRAW);
    for (GLuint attribute = 0; attribute < 5; ++attribute) {
      gl().EnableVertexAttribArray(attribute);
      // GL takes the attribute's offset in the bound buffer as a pointer.
      const std::uintptr_t offset = std::uintptr_t{attribute} * 3 * sizeof(float);
      gl().VertexAttribPointer(attribute, 3, GL_FLOAT, GL_FALSE, sizeof(Vertex),
                               reinterpret_cast<const void*>(offset));  // NOLINT(performance-no-int-to-ptr): GL's API
    }
    gl().GenBuffers(1, &index_buffer);
    gl().BindBuffer(GL_ELEMENT_ARRAY_BUFFER, index_buffer);
    static_assert(sizeof(mesh::Triangle) == 3 * sizeof(std::uint32_t));
    gl().BufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(order.triangles.size() * sizeof(mesh::Triangle)),
                    order.triangles.data(), GL_STATIC_DRAW);
    index_count = static_cast<GLsizei>(order.triangles.size() * 3);
    if (precull) {
      draw_triangles = order.triangles;
      draw_rest.resize(vertices.size());
      draw_field.resize(vertices.size());
      for (std::size_t k = 0; k < vertices.size(); ++k) {
        draw_rest[k] = Eigen::Vector3f(vertices[k].rest[0], vertices[k].rest[1], vertices[k].rest[2]);
        draw_field[k] = Eigen::Vector3f(vertices[k].field[0], vertices[k].field[1], vertices[k].field[2]);
      }
      gl().GenBuffers(1, &visible_buffer);
    }
    gl().BindVertexArray(0);
  }

  GLuint renderbuffer(GLenum format, int sample_count) {
    GLuint rb = 0;
    gl().GenRenderbuffers(1, &rb);
    gl().BindRenderbuffer(GL_RENDERBUFFER, rb);
    if (sample_count > 1) {
      gl().RenderbufferStorageMultisample(GL_RENDERBUFFER, sample_count, format, options.width, options.height);
    } else {
      gl().RenderbufferStorage(GL_RENDERBUFFER, format, options.width, options.height);
    }
    return rb;
  }

  void check_framebuffer(const char* what) {
    const GLenum status = gl().CheckFramebufferStatus(GL_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE) {
      throw UnsupportedError(std::string("render: the OpenGL driver cannot make the ") + what +
                             " framebuffer (status 0x" + fmt_hex(status) + ")");
    }
  }
  static std::string fmt_hex(GLenum value) {
    char text[16];
    std::snprintf(text, sizeof text, "%x", value);
    return text;
  }

  void create_framebuffers() {
    GLint max_size = 0, max_samples = 0;
    gl().GetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_size);
    gl().GetIntegerv(GL_MAX_SAMPLES, &max_samples);
    if (options.width > max_size || options.height > max_size) {
      throw UnsupportedError("render: image size " + std::to_string(options.width) + "x" +
                             std::to_string(options.height) + " exceeds the OpenGL limit of " +
                             std::to_string(max_size) + " pixels per side");
    }
    samples = options.msaa_samples > 1 ? std::min(options.msaa_samples, static_cast<int>(max_samples)) : 0;
    if (samples == 1) samples = 0;

    // The single-sampled image: a texture, so that FXAA can sample it.
    gl().GenTextures(1, &image_texture);
    gl().BindTexture(GL_TEXTURE_2D, image_texture);
    gl().TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, options.width, options.height, 0, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
    gl().TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    gl().TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    gl().TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    gl().TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    gl().GenFramebuffers(1, &image_fbo);
    gl().BindFramebuffer(GL_FRAMEBUFFER, image_fbo);
    gl().FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, image_texture, 0);
    if (samples == 0) {
      depth_rb = renderbuffer(GL_DEPTH_COMPONENT24, 0);
      gl().FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_rb);
    }
    check_framebuffer("image");

    if (samples > 0) {
      gl().GenFramebuffers(1, &msaa_fbo);
      gl().BindFramebuffer(GL_FRAMEBUFFER, msaa_fbo);
      msaa_colour_rb = renderbuffer(GL_RGBA8, samples);
      msaa_depth_rb = renderbuffer(GL_DEPTH_COMPONENT24, samples);
      gl().FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, msaa_colour_rb);
      gl().FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, msaa_depth_rb);
      check_framebuffer("multisampled");
    }
    if (options.fxaa) {
      gl().GenFramebuffers(1, &output_fbo);
      gl().BindFramebuffer(GL_FRAMEBUFFER, output_fbo);
      output_rb = renderbuffer(GL_RGBA8, 0);
      gl().FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, output_rb);
      check_framebuffer("output");
    }
    const auto bytes = static_cast<GLsizeiptr>(options.width) * options.height * 4;
    for (Readback& slot : readbacks) {
      gl().GenBuffers(1, &slot.buffer);
      gl().BindBuffer(GL_PIXEL_PACK_BUFFER, slot.buffer);
      gl().BufferData(GL_PIXEL_PACK_BUFFER, bytes, nullptr, GL_STREAM_READ);
    }
    gl().BindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  }

  // Clear, draw every surface at its s, resolve MSAA, filter (FXAA): the frame is then in
  // readback_fbo().
  void draw(std::span<const double> s) {
    const auto& gl = this->gl();
    const int w = options.width, h = options.height;
    gl.BindFramebuffer(GL_FRAMEBUFFER, draw_fbo());
    gl.Viewport(0, 0, w, h);
    const Eigen::Vector3d& bg = options.background;
    gl.ClearColor(static_cast<float>(bg.x()), static_cast<float>(bg.y()), static_cast<float>(bg.z()), 1.0f);
    gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    if (index_count > 0) {
      gl.UseProgram(program);
      for (std::size_t p = 0; p < parts.size(); ++p) {
        const Part& part = parts[p];
        gl.Uniform1f(s_location, static_cast<float>(s[p]));
        if (p == 0) gl.BindVertexArray(vao);
        const bool culled = draws_visible_only(part, s[p]);
        gl.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, culled ? visible_buffer : index_buffer);
        const GLsizei first = culled ? part.visible_begin : part.index_begin;
        // GL takes the offset in the bound element buffer as a pointer.
        const std::uintptr_t offset = static_cast<std::uintptr_t>(first) * sizeof(std::uint32_t);
        gl.DrawElements(GL_TRIANGLES, culled ? part.visible_count : part.index_count, GL_UNSIGNED_INT,
                        reinterpret_cast<const void*>(offset));  // NOLINT(performance-no-int-to-ptr): GL's API
      }
      gl.BindVertexArray(0);
    }
    if (samples > 0) {
      gl.BindFramebuffer(GL_READ_FRAMEBUFFER, msaa_fbo);
      gl.BindFramebuffer(GL_DRAW_FRAMEBUFFER, image_fbo);
      gl.BlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    }
    if (options.fxaa) {
      gl.BindFramebuffer(GL_FRAMEBUFFER, output_fbo);
      gl.Disable(GL_DEPTH_TEST);
      gl.UseProgram(fxaa_program);
      gl.ActiveTexture(GL_TEXTURE0);
      gl.BindTexture(GL_TEXTURE_2D, image_texture);
      gl.BindVertexArray(empty_vao);
      gl.DrawArrays(GL_TRIANGLES, 0, 3);
      gl.BindVertexArray(0);
      gl.Enable(GL_DEPTH_TEST);
    }
  }

  GLuint draw_fbo() const { return samples > 0 ? msaa_fbo : image_fbo; }
  GLuint readback_fbo() const { return options.fxaa ? output_fbo : image_fbo; }

  void apply_camera() {
    const double aspect = static_cast<double>(options.width) / options.height;
    Eigen::Affine3d model_to_world = Eigen::Affine3d::Identity();
    model_to_world.translate(origin);
    const Eigen::Matrix4f view = (view_matrix(camera) * model_to_world.matrix()).cast<float>();
    const Eigen::Matrix4f projection = projection_matrix(camera, aspect).cast<float>();
    gl().UseProgram(program);
    gl().UniformMatrix4fv(view_location, 1, GL_FALSE, view.data());  // Eigen is column-major, as GL
    gl().UniformMatrix4fv(projection_location, 1, GL_FALSE, projection.data());
    // The inverse of the projection along a pixel's view ray, for the fragment shader's view
    // direction: normalized device x = 2 x_window / width - 1, and view x / -z = ndc x * aspect / f.
    const double f = projection(1, 1);
    gl().Uniform2f(ray_scale_location, static_cast<float>(2.0 * aspect / (f * options.width)),
                   static_cast<float>(2.0 / (f * options.height)));
    gl().Uniform2f(ray_offset_location, static_cast<float>(-aspect / f), static_cast<float>(-1.0 / f));
    if (precull) upload_visible_triangles();
  }

  // The pre-cull (faces_away_throughout) for the current camera, uploaded as visible_buffer.
  void upload_visible_triangles() {
    const Eigen::Vector3d eye = camera.eye - origin, forward = (camera.target - camera.eye).normalized();
    std::vector<mesh::Triangle> visible;
    visible.reserve(draw_triangles.size());
    for (Part& part : parts) {
      part.visible_begin = static_cast<GLsizei>(visible.size() * 3);
      const auto begin = static_cast<std::size_t>(part.index_begin / 3);
      const auto end = begin + static_cast<std::size_t>(part.index_count / 3);
      for (std::size_t k = begin; k < end; ++k) {
        const mesh::Triangle& t = draw_triangles[k];
        const std::array<Eigen::Vector3d, 3> p{draw_rest[t[0]].cast<double>(), draw_rest[t[1]].cast<double>(),
                                               draw_rest[t[2]].cast<double>()};
        const std::array<Eigen::Vector3d, 3> u{draw_field[t[0]].cast<double>(), draw_field[t[1]].cast<double>(),
                                               draw_field[t[2]].cast<double>()};
        if (!faces_away_throughout(p, u, eye, forward, camera.near_m, part.scales)) visible.push_back(t);
      }
      part.visible_count = static_cast<GLsizei>(visible.size() * 3) - part.visible_begin;
    }
    // Filled through the array-buffer binding (global state, unlike the element binding, which
    // belongs to the vertex array); the draw binds it as the element buffer.
    gl().BindBuffer(GL_ARRAY_BUFFER, visible_buffer);
    gl().BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(visible.size() * sizeof(mesh::Triangle)), visible.data(),
                    GL_STATIC_DRAW);
    gl().BindBuffer(GL_ARRAY_BUFFER, 0);
    visible_index_count = static_cast<GLsizei>(visible.size() * 3);
  }

  // Whether a frame draws a part's pre-culled triangles at s (they hold for its range only).
  bool draws_visible_only(const Part& part, double s) const {
    return precull && s >= part.scales.min && s <= part.scales.max;
  }

  void check_gl(const char* where) {
    const GLenum error = gl().GetError();
    if (error != GL_NO_ERROR)
      throw Error(ExitCode::failure, std::string("render: OpenGL error 0x") + fmt_hex(error) + " in " + where);
  }

  ~Impl() {
    context.make_current();
    for (Readback& slot : readbacks) {
      if (slot.fence != nullptr) gl().DeleteSync(slot.fence);
      gl().DeleteBuffers(1, &slot.buffer);
    }
    // Deleting the name 0 is a no-op, so unused objects need no special case.
    const GLuint framebuffers[] = {msaa_fbo, image_fbo, output_fbo};
    gl().DeleteFramebuffers(3, framebuffers);
    const GLuint renderbuffers[] = {msaa_colour_rb, msaa_depth_rb, depth_rb, output_rb};
    gl().DeleteRenderbuffers(4, renderbuffers);
    gl().DeleteTextures(1, &image_texture);
    gl().DeleteVertexArrays(1, &empty_vao);
    gl().DeleteProgram(fxaa_program);
    const GLuint buffers[] = {vertex_buffer, index_buffer, visible_buffer};
    gl().DeleteBuffers(3, buffers);
    gl().DeleteVertexArrays(1, &vao);
    gl().DeleteProgram(program);
  }
};

Renderer::Renderer(const mesh::TriangleMesh& rest, const std::vector<Eigen::Vector3d>& field, ScaleRange scales,
                   const RenderOptions& options)
    : Renderer(std::span<const RenderPart>(std::array<RenderPart, 1>{RenderPart{&rest, &field, scales}}), options) {}

Renderer::Renderer(std::span<const RenderPart> surfaces, const RenderOptions& options) {
  if (options.width < 1 || options.height < 1) {
    throw UsageError("render: image size " + std::to_string(options.width) + "x" + std::to_string(options.height) +
                     ": width and height must be at least 1 pixel");
  }
  if (surfaces.empty()) throw ValueError("render: no surface to draw");
  for (const RenderPart& part : surfaces) {
    const mesh::TriangleMesh& rest = *part.rest;
    const std::vector<Eigen::Vector3d>& field = *part.field;
    const ScaleRange& scales = part.scales;
    if (field.size() != rest.vertex_count()) {
      throw InputError("render: the field has " + std::to_string(field.size()) + " vectors but the mesh has " +
                       std::to_string(rest.vertex_count()) + " vertices");
    }
    for (std::size_t t = 0; t < rest.triangles.size(); ++t) {
      for (std::uint32_t v : rest.triangles[t]) {
        if (v >= rest.vertex_count()) {
          throw InputError("render: triangle " + std::to_string(t) + " refers to vertex " + std::to_string(v) + " of " +
                           std::to_string(rest.vertex_count()));
        }
      }
    }
    if (!std::isfinite(scales.min) || !std::isfinite(scales.max) || scales.min > scales.max) {
      throw InputError("render: the range of scales [" + std::to_string(scales.min) + ", " +
                       std::to_string(scales.max) + "] is not an interval of finite numbers");
    }
  }

  impl_ = std::make_unique<Impl>(options.gl);
  Impl& r = *impl_;
  r.options = options;
  std::size_t vertex_count = 0;
  double max_field = 0.0, overlay_reach = 0.0;
  for (std::size_t p = 0; p < surfaces.size(); ++p) {
    const RenderPart& part = surfaces[p];
    const auto box = bounds_over_range(*part.rest, *part.field, part.scales);
    r.bounds =
        p == 0 ? box : std::array<Eigen::Vector3d, 2>{r.bounds[0].cwiseMin(box[0]), r.bounds[1].cwiseMax(box[1])};
    vertex_count += part.rest->vertex_count();
    double part_max = 0.0;
    for (const auto& u : *part.field) part_max = std::max(part_max, u.norm());
    max_field = std::max(max_field, part_max);
    overlay_reach = std::max(overlay_reach, part_max * std::max(std::abs(part.scales.min), std::abs(part.scales.max)));
    r.parts.push_back({part.scales});
  }
  if (vertex_count > 0) r.origin = 0.5 * (r.bounds[0] + r.bounds[1]);
  r.camera = frame_camera(options.camera, r.bounds, static_cast<double>(options.width) / options.height,
                          options.fov_y_deg, options.margin);
  r.overlay_max = options.overlay_max_m > 0.0 ? options.overlay_max_m : overlay_reach;
  if (!(r.overlay_max > 0.0)) r.overlay_max = 1e-3;  // a field of zeros: any positive scale shows 0

  const auto& gl = r.gl();
  // PNEUMA_DRAW_ALL_TRIANGLES=1 turns the pre-cull off (to compare; the image is the same).
  const char* draw_all = std::getenv("PNEUMA_DRAW_ALL_TRIANGLES");
  r.precull = options.cull_back_faces && !(draw_all && std::string(draw_all) == "1");
  r.create_framebuffers();
  if (options.fxaa) r.build_fxaa();
  r.build_program();
  r.upload(surfaces);
  r.apply_camera();
  gl.Enable(GL_DEPTH_TEST);
  gl.DepthFunc(GL_LESS);
  if (options.cull_back_faces) {
    gl.Enable(GL_CULL_FACE);
    gl.CullFace(GL_BACK);
  }
  if (r.samples > 0) gl.Enable(GL_MULTISAMPLE);
  gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
  r.check_gl("set-up");
}

Renderer::~Renderer() = default;

Image Renderer::render(double s) {
  Image image;
  render(s, image);
  return image;
}

void Renderer::render(double s, Image& out) {
  const std::array<double, 1> one{s};
  render(std::span<const double>(one), out);
}

Image Renderer::render(std::span<const double> s) {
  Image image;
  render(s, image);
  return image;
}

void Renderer::render(std::span<const double> s, Image& out) {
  if (impl_->in_flight > 0)
    throw Error(ExitCode::failure, "render: render() with frames in flight (collect them first)");
  submit(s);
  collect(out);
}

void Renderer::submit(double s) {
  const std::array<double, 1> one{s};
  submit(std::span<const double>(one));
}

void Renderer::submit(std::span<const double> s) {
  Impl& r = *impl_;
  if (s.size() != r.parts.size())
    throw ValueError("render: " + std::to_string(r.parts.size()) + " scales expected, one per surface");
  if (r.in_flight == max_frames_in_flight)
    throw Error(ExitCode::failure,
                "render: " + std::to_string(max_frames_in_flight) + " frames in flight already (collect one first)");
  const auto& gl = r.gl();
  r.context.make_current();
  r.draw(s);
  Impl::Readback& slot = r.readbacks[(r.oldest + r.in_flight) % max_frames_in_flight];
  gl.BindFramebuffer(GL_READ_FRAMEBUFFER, r.readback_fbo());
  gl.ReadBuffer(GL_COLOR_ATTACHMENT0);
  gl.BindBuffer(GL_PIXEL_PACK_BUFFER, slot.buffer);
  gl.ReadPixels(0, 0, r.options.width, r.options.height, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
  gl.BindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  slot.fence = gl.FenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  gl.Flush();  // the GPU starts on this frame now, not when it is collected
  r.check_gl("render");
  ++r.in_flight;
}

void Renderer::collect(Image& out) {
  Impl& r = *impl_;
  if (r.in_flight == 0) throw Error(ExitCode::failure, "render: collect() with no frame in flight");
  const auto& gl = r.gl();
  const int w = r.options.width, h = r.options.height;
  if (out.width != w || out.height != h || out.rgba.size() != out.pixel_count() * 4) out = Image(w, h);
  r.context.make_current();
  Impl::Readback& slot = r.readbacks[r.oldest];
  r.oldest = (r.oldest + 1) % max_frames_in_flight;
  --r.in_flight;
  constexpr GLuint64 kSecond_ns = 1'000'000'000;
  GLenum waited = GL_TIMEOUT_EXPIRED;
  while (waited == GL_TIMEOUT_EXPIRED) waited = gl.ClientWaitSync(slot.fence, GL_SYNC_FLUSH_COMMANDS_BIT, kSecond_ns);
  gl.DeleteSync(slot.fence);
  slot.fence = nullptr;
  if (waited == GL_WAIT_FAILED) r.check_gl("waiting for a frame");
  const std::size_t stride = static_cast<std::size_t>(w) * 4;
  gl.BindBuffer(GL_PIXEL_PACK_BUFFER, slot.buffer);
  const auto* pixels = static_cast<const std::uint8_t*>(
      gl.MapBufferRange(GL_PIXEL_PACK_BUFFER, 0, static_cast<GLsizeiptr>(stride * h), GL_MAP_READ_BIT));
  if (pixels == nullptr) {
    gl.BindBuffer(GL_PIXEL_PACK_BUFFER, 0);
    r.check_gl("mapping a frame");
    throw Error(ExitCode::failure, "render: the OpenGL driver did not map the frame's pixels");
  }
  // OpenGL's first row is the bottom one; images here start at the top.
  for (int y = 0; y < h; ++y)
    std::memcpy(out.rgba.data() + static_cast<std::size_t>(y) * stride,
                pixels + static_cast<std::size_t>(h - 1 - y) * stride, stride);
  gl.UnmapBuffer(GL_PIXEL_PACK_BUFFER);
  gl.BindBuffer(GL_PIXEL_PACK_BUFFER, 0);
  r.check_gl("read-back");
  if (r.options.overlay_magnitude && r.options.legend) detail::draw_legend(out, r.overlay_max);
}

std::size_t Renderer::frames_in_flight() const { return impl_->in_flight; }

void Renderer::set_camera(CameraPreset preset) {
  const RenderOptions& o = impl_->options;
  set_camera(frame_camera(preset, impl_->bounds, static_cast<double>(o.width) / o.height, o.fov_y_deg, o.margin));
}

void Renderer::set_camera(const Camera& camera) {
  impl_->camera = camera;
  impl_->context.make_current();
  impl_->apply_camera();
}

const Camera& Renderer::camera() const { return impl_->camera; }
const RenderOptions& Renderer::options() const { return impl_->options; }
const std::array<Eigen::Vector3d, 2>& Renderer::framed_bounds() const { return impl_->bounds; }
double Renderer::overlay_max_m() const { return impl_->overlay_max; }
std::string Renderer::gl_renderer() const { return impl_->context.renderer(); }
std::string Renderer::gl_version() const { return impl_->context.version(); }
std::string Renderer::gl_backend() const { return impl_->context.backend(); }

bool parse_gl_backend(const std::string& text, GlBackend& out) {
  if (text == "auto") out = GlBackend::automatic;
  else if (text == "egl") out = GlBackend::egl;
  else if (text == "osmesa") out = GlBackend::osmesa;
  else return false;
  return true;
}
int Renderer::msaa_samples() const { return impl_->samples; }
std::size_t Renderer::drawn_triangles(double s) const {
  const Impl& r = *impl_;
  std::size_t count = 0;
  for (const Impl::Part& part : r.parts)
    count += static_cast<std::size_t>(r.draws_visible_only(part, s) ? part.visible_count : part.index_count) / 3;
  return count;
}

}  // namespace pneuma::render
