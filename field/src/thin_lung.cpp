#include "pneuma/field/thin_lung.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>

#include "fixed_blocks.h"
#include "pneuma/core/error.h"
#include "pneuma/field/heart.h"
#include "pneuma/mesh/anatomy/regions.h"
#include "pneuma/mesh/geometry/surface_hits.h"
#include "pneuma/mesh/geometry/vertex_neighbours.h"
#include "step_down.h"

namespace pneuma::field {

namespace {
// Rounds of asking and averaging: a pair whose vertices have no other request gives up its
// full excess in one round; neighbouring rays' requests agree after a few tens.
constexpr int kRounds = 40;
// Passes of the surface's umbrella average (half the vertex, half its neighbours' mean) over
// the change: without them neighbouring vertices whose rays ask differently (one finds a face
// across, the next misses it) stepped apart, and at a 1.5 L breath the surface of every case
// self-intersected (CtLungRealism); with 4 passes case008's left lung upright still did.
constexpr int kSmoothingPasses = 8;

using detail::for_each_index;  // each vertex writes its own slot: the same bits at any thread count
using detail::step_down;

std::vector<Eigen::Vector3d> umbrella_smoothed(const mesh::TriangleMesh& mesh, std::vector<Eigen::Vector3d> change) {
  const std::size_t n = change.size();
  // Rows ascending, the order unique_edges gave the sums before (the same bits).
  const mesh::VertexNeighbours around(mesh);
  std::vector<Eigen::Vector3d> next(n);
  for (int pass = 0; pass < kSmoothingPasses; ++pass) {
    // Each vertex reads the previous pass only.
    for_each_index(n, [&](std::size_t i) {
      const std::span<const std::uint32_t> row = around(i);
      if (row.empty()) {
        next[i] = change[i];
        return;
      }
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (const std::uint32_t j : row) sum += change[j];
      next[i] = 0.5 * change[i] + 0.5 * sum / static_cast<double>(row.size());
    });
    change.swap(next);
  }
  return change;
}
}  // namespace

double mean_volume_strain(const mesh::TriangleMesh& mesh, const std::vector<Eigen::Vector3d>& u) {
  if (u.size() != mesh.vertices.size()) throw ValueError("mean_volume_strain: one displacement per vertex");
  const double volume = mesh::enclosed_volume(mesh);
  if (!(volume > 0.0)) throw ValueError("mean_volume_strain: the surface encloses no volume (closed, outward)");
  const std::vector<Eigen::Vector3d> gradient = mesh::volume_gradient(mesh);
  double rate = 0.0;
  for (std::size_t i = 0; i < u.size(); ++i) rate += gradient[i].dot(u[i]);
  return rate / volume;
}

void limit_the_stretch_across_thin_parts(const mesh::TriangleMesh& mesh, std::vector<Eigen::Vector3d>& u, double high,
                                         const ThinLung& thin) {
  if (u.size() != mesh.vertices.size())
    throw ValueError("limit_the_stretch_across_thin_parts: one displacement per vertex");
  limit_the_stretch_across_thin_parts(mesh, u, high, thin, mesh::smoothed_normals(mesh, kFaceNormalSigma));
}

void limit_the_stretch_across_thin_parts(const mesh::TriangleMesh& mesh, std::vector<Eigen::Vector3d>& u, double high,
                                         const ThinLung& thin, const std::vector<Eigen::Vector3d>& face_normal) {
  if (u.size() != mesh.vertices.size() || face_normal.size() != mesh.vertices.size())
    throw ValueError("limit_the_stretch_across_thin_parts: one displacement and one smoothed normal per vertex");
  if (!(thin.thin > 0.0 && thin.thick > thin.thin))
    throw ValueError("limit_the_stretch_across_thin_parts: expected 0 < thin < thick");
  const std::size_t n = u.size();
  std::vector<Eigen::Vector3d> inward(n);
  // Inward along the 3 mm normals (heart.h, kFaceNormalSigma): a thin part's two faces keep their own.
  for (std::size_t i = 0; i < n; ++i) inward[i] = -face_normal[i];
  const std::vector<mesh::SurfaceHit> hits = mesh::first_hits_from_vertices(mesh, inward, thin.thick);
  const std::vector<Eigen::Vector3d> before = u;
  std::vector<Eigen::Vector3d> asked(n);
  std::vector<double> askers(n);
  std::vector<double> excess(n);
  for (int round = 0; round < kRounds; ++round) {
    // Each ray's excess reads this round's u only (on every thread); the requests are then
    // gathered in vertex order on one, so the sums keep their order and their bits.
    for_each_index(n, [&](std::size_t i) {
      const mesh::SurfaceHit& hit = hits[i];
      if (!hit.found) return;
      const auto& face = mesh.triangles[hit.face];
      Eigen::Vector3d across = Eigen::Vector3d::Zero();
      for (std::size_t k = 0; k < 3; ++k) across += hit.weights[k] * u[face[k]];
      const double strain = (across - u[i]).dot(inward[i]) / hit.distance;
      // The excess fully where the part is thin, none where it is thick, a smooth step between.
      excess[i] = std::max(0.0, strain - high) * hit.distance *
                  step_down((hit.distance - thin.thin) / (thin.thick - thin.thin));
    });
    std::fill(asked.begin(), asked.end(), Eigen::Vector3d::Zero());
    std::fill(askers.begin(), askers.end(), 0.0);
    bool any = false;
    for (std::size_t i = 0; i < n; ++i) {
      const mesh::SurfaceHit& hit = hits[i];
      if (!hit.found) continue;
      const auto& face = mesh.triangles[hit.face];
      const Eigen::Vector3d& d = inward[i];
      // Every ray that finds a face across votes, so a vertex whose rays agree keeps its place.
      askers[i] += 1.0;
      if (excess[i] > 0.0) {
        any = true;
        asked[i] += 0.5 * excess[i] * d;
      }
      for (std::size_t k = 0; k < 3; ++k) {
        askers[face[k]] += hit.weights[k];
        if (excess[i] > 0.0) asked[face[k]] -= hit.weights[k] * 0.5 * excess[i] * d;
      }
    }
    if (!any) break;
    for_each_index(n, [&](std::size_t i) {
      if (askers[i] > 0.0) u[i] += asked[i] / askers[i];
    });
  }
  std::vector<Eigen::Vector3d> change(n);
  for (std::size_t i = 0; i < n; ++i) change[i] = u[i] - before[i];
  change = umbrella_smoothed(mesh, std::move(change));
  for (std::size_t i = 0; i < n; ++i) u[i] = before[i] + change[i];
}

namespace {
// The lung's own bound, m (1 + spread) with m its mean volume strain under u; none (nullopt) where
// m <= 0: a field that does not inflate the lung has no stretch to bound.
std::optional<double> lung_bound(const mesh::TriangleMesh& mesh, const std::vector<Eigen::Vector3d>& u,
                                 const ThinLung& thin) {
  if (!(thin.spread >= 0.0)) throw ValueError("limit_the_stretch_across_thin_lung: expected a spread >= 0");
  const double mean = mean_volume_strain(mesh, u);
  if (!(mean > 0.0)) return std::nullopt;
  return mean * (1.0 + thin.spread);
}
}  // namespace

void limit_the_stretch_across_thin_lung(const mesh::TriangleMesh& mesh, std::vector<Eigen::Vector3d>& u,
                                        const ThinLung& thin) {
  if (const auto high = lung_bound(mesh, u, thin)) limit_the_stretch_across_thin_parts(mesh, u, *high, thin);
}

void limit_the_stretch_across_thin_lung(const mesh::TriangleMesh& mesh, std::vector<Eigen::Vector3d>& u,
                                        const ThinLung& thin, const std::vector<Eigen::Vector3d>& face_normal) {
  if (const auto high = lung_bound(mesh, u, thin))
    limit_the_stretch_across_thin_parts(mesh, u, *high, thin, face_normal);
}

void limit_the_stretch_across_thin_lung(const mesh::TriangleMesh& mesh, const mesh::SurfaceProxy& proxy,
                                        std::vector<Eigen::Vector3d>& u, const ThinLung& thin,
                                        const std::vector<Eigen::Vector3d>& face_normal) {
  const auto high = lung_bound(mesh, u, thin);
  if (!high) return;
  const std::size_t m = proxy.fine_vertex.size();
  std::vector<Eigen::Vector3d> before(m), normal(m);
  for (std::size_t j = 0; j < m; ++j) {
    before[j] = u[proxy.fine_vertex[j]];
    normal[j] = face_normal[proxy.fine_vertex[j]];
  }
  std::vector<Eigen::Vector3d> limited = before;
  limit_the_stretch_across_thin_parts(proxy.mesh, limited, *high, thin, normal);
  for (std::size_t j = 0; j < m; ++j) limited[j] -= before[j];
  const std::vector<Eigen::Vector3d> change = mesh::transferred_to_fine(mesh, proxy, limited);
  for (std::size_t i = 0; i < u.size(); ++i) u[i] += change[i];
}

}  // namespace pneuma::field
