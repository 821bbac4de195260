#pragma once
// Anatomical regions of one lung surface, found from its geometry alone, and the smooth
// direction fields the elastostatic field can push along (docs/realism.md).
//
// Body frame. `up` (superior) and `anterior` are given (DICOM LPS: up +z, anterior -y, the
// built-in phantom's frame); `left = up x anterior` is the patient's left (+x in LPS). The
// side of the lung is found, not given: its mediastinal (medial) face is the one toward the
// body midline, which is the concave face (cardiac impression, hilum, the groove around the
// mediastinum); the costal face is convex, on the convex hull. So the face (along +left or
// -left) that lies deeper below the convex hull of the surface is medial.
//
// Regions (per vertex, from the normals of the surface smoothed at `classification_length_m`
// and the height between the lowest and highest vertex, 0 at the base, 1 at the apex):
//   diaphragmatic  the inferior surface whose normals point down: -n.up rises through
//                  `diaphragm_cos` (smoothly over +/- `transition`), in the lower `diaphragm_height`
//   apex           above `apex_height` of the height (the cupola above the first rib)
//   mediastinal    the medial face, hilum included: n.medial rises through `medial_cos`
//   costal         the rest: the rib-cage surface (lateral, anterior and posterior)
// Weights are products of smooth steps, taken in that order, so every vertex's four weights
// are >= 0 and add up to 1 (a partition of unity); the label is the largest weight.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/mesh/anatomy/lung.h"
#include "pneuma/mesh/geometry/surface_proxy.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

enum class Region : std::uint8_t { apex = 0, costal = 1, diaphragmatic = 2, mediastinal = 3 };
inline constexpr std::size_t kRegionCount = 4;
inline constexpr std::array<Region, kRegionCount> kRegions{Region::apex, Region::costal, Region::diaphragmatic,
                                                           Region::mediastinal};
// "apex", "costal", "diaphragmatic", "mediastinal".
std::string_view region_name(Region region);
// The region of a name above, or nothing.
std::optional<Region> region_from_name(std::string_view name);

struct BodyAxes {
  Eigen::Vector3d up{0.0, 0.0, 1.0};         // superior (LPS: +z)
  Eigen::Vector3d anterior{0.0, -1.0, 0.0};  // LPS: -y (y is posterior)
  // The patient's left: up x anterior (LPS: +x).
  Eigen::Vector3d left() const { return up.cross(anterior).normalized(); }
};

struct RegionOptions {
  BodyAxes axes;
  std::optional<Lung> side;               // nothing: found from the geometry
  double classification_length_m = 0.01;  // Gaussian smoothing of the normals (mesh units)
  double diaphragm_cos = 0.4;             // -n.up at the diaphragmatic border (about 24 deg below horizontal)
  double diaphragm_height = 0.55;         // the diaphragm lies below this height
  double apex_height = 0.85;              // the apex lies above this height
  double medial_cos = 0.45;               // n.medial at the mediastinal border
  double transition = 0.35;               // half-width of the smooth steps in a cosine (wide: docs/realism.md, 4.)
  double height_transition = 0.05;        // half-width of the smooth steps in height
  // The side's hull depths are measured below the convex hull of a coarse proxy of the surface:
  // its vertices thinned to one per cell of this size (hull_proxy_points). 0: every vertex.
  // 4 mm: the hull is a fixed cost at any resolution (9,000-12,000 points on a lung), and the
  // side's depths move by < 0.01 mm on the phantom and < 0.2 mm on CT lungs against 2 mm (#50).
  double hull_proxy_cell_m = 4e-3;
  // The side's mean depths are taken over at most this many of the steep vertices (every k-th in
  // index order): a query deep inside the hull costs 10-80 us.
  std::size_t side_sample = 1000;
};
inline const RegionOptions kDefaultRegionOptions{};

struct SurfaceRegions {
  Lung side = Lung::right;
  Eigen::Vector3d medial = Eigen::Vector3d::UnitX();  // unit, toward the body midline
  BodyAxes axes;
  std::vector<Region> label;                             // per vertex: the largest weight
  std::vector<std::array<double, kRegionCount>> weight;  // per vertex, indexed by Region, sum 1
  std::vector<double> height;                            // per vertex: 0 at the lowest, 1 at the highest
  std::vector<Eigen::Vector3d> normal;                   // per vertex: the smoothed normal classified
  // The mean depth below the convex hull (m) of the faces toward +left and -left that decided the side.
  double left_face_depth = 0.0, right_face_depth = 0.0;
};

// Throws ValueError for an empty mesh or an up/anterior pair that is not at right angles.
// `proxy` (mesh::proxy_for(mesh), or null): the normals are smoothed from it (smoothed_normals below).
SurfaceRegions find_regions(const TriangleMesh& mesh, const RegionOptions& options = kDefaultRegionOptions,
                            const SurfaceProxy* proxy = nullptr);

// Throws ValueError ("<who>: the regions given are of another surface or body frame") unless
// `regions` hold one entry per vertex of `mesh` and were found in `frame`: regions found once
// and handed on are checked where they are used.
void require_regions_of(const SurfaceRegions& regions, const TriangleMesh& mesh, const BodyAxes& frame,
                        const char* who);

// Per vertex: the outward normal of the surface blurred by a Gaussian of standard deviation
// `sigma` (mesh units), N(x) = sum_t G(x - c_t) A_t n_t = -grad (G * chi)(x), chi the inside,
// normalised. A smooth field in space, not only along the surface: the two lips of a narrow
// crease get nearly the same direction, so moving along it cannot close the crease.
// Computed on a grid (spacing sigma / 2: splat, separable blur, trilinear interpolation), in a
// fixed order: the same mesh gives the same bits. Where the blurred field vanishes (|N| below
// 1e-9 of its largest value), the vertex normal. Throws ValueError for sigma <= 0.
std::vector<Eigen::Vector3d> smoothed_normals(const TriangleMesh& mesh, double sigma);
// The same field blurred from the triangles of `proxy` (mesh::surface_proxy of `mesh`) and read at
// the vertices of `mesh`: a field in space at sigma of 3 mm or more, its splat over a few
// thousand triangles instead of millions (#50); the vertex normals of `mesh` where it vanishes.
// proxy null: smoothed_normals(mesh, sigma). Throws ValueError for a proxy of another mesh.
std::vector<Eigen::Vector3d> smoothed_normals(const TriangleMesh& mesh, const SurfaceProxy* proxy, double sigma);

// Per vertex: the area-weighted Gaussian average in space (standard deviation `sigma`, mesh
// units) of a per-vertex value, sum_j G(x_i - x_j) A_j v_j / sum_j G(x_i - x_j) A_j, on the grid of
// smoothed_normals(): smooth in space, so vertices close in space get close values however far
// apart they lie along the surface. Deterministic. Throws ValueError for sigma <= 0 or a size
// other than one value per vertex.
std::vector<double> blurred_in_space(const TriangleMesh& mesh, const std::vector<double>& value, double sigma);
// The same for two or three values per vertex at once, with the vertex areas given
// (vertex_areas(mesh)): one grid, each value blurred to the bits blurred_in_space gives it alone
// (a grid per value cost the recess rule eight passes over the vertices, #50). Throws ValueError
// as above, and for a size other than one area per vertex.
std::vector<Eigen::Vector2d> blurred_in_space(const TriangleMesh& mesh, const std::vector<double>& area,
                                              const std::vector<Eigen::Vector2d>& value, double sigma);
std::vector<Eigen::Vector3d> blurred_in_space(const TriangleMesh& mesh, const std::vector<double>& area,
                                              const std::vector<Eigen::Vector3d>& value, double sigma);

// Per vertex: the mean curvature (1/length, > 0 where convex) from the cotangent Laplacian,
// H_i = -(Delta x)_i . n_i / 2, Delta the cotangent Laplacian over the barycentric vertex area.
std::vector<double> mean_curvature(const TriangleMesh& mesh);

// The convex hull of a point set, built once (CGAL hull, an AABB tree over its faces), and the
// depth below it of any points: their distance below the hull (0 on the hull or outside it).
// Queries inside a large hull cost ~50-80 us each at 10^5 hull faces, so ask for the points you
// need. Building and querying are apart so that the build can run beside other work.
class ConvexHullDepth {
 public:
  explicit ConvexHullDepth(const std::vector<Eigen::Vector3d>& points);
  ~ConvexHullDepth();
  ConvexHullDepth(const ConvexHullDepth&) = delete;
  ConvexHullDepth& operator=(const ConvexHullDepth&) = delete;
  std::vector<double> depth(const std::vector<Eigen::Vector3d>& queries) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Per query point: its distance below the convex hull of `points` (ConvexHullDepth).
std::vector<double> depth_below_convex_hull(const std::vector<Eigen::Vector3d>& points,
                                            const std::vector<Eigen::Vector3d>& queries);
// Per point: its distance below the convex hull of all the points.
inline std::vector<double> depth_below_convex_hull(const std::vector<Eigen::Vector3d>& points) {
  return depth_below_convex_hull(points, points);
}

// A coarse proxy of a point set for its convex hull: one point per occupied cell of a grid of
// spacing `cell` (the one farthest from the points' mean, the lowest index on a tie), in cell
// order. Every point lies within a cell's diagonal of a kept one, and on a smooth surface of
// curvature radius R the proxy's hull lies within about cell^2 / R of the whole hull (a few
// hundredths of a millimetre on a lung at 2 mm), at a cost that does not grow with the mesh's
// resolution. The grid grows coarser past 2e6 cells. cell <= 0: the points as they are.
std::vector<Eigen::Vector3d> hull_proxy_points(const std::vector<Eigen::Vector3d>& points, double cell);

// Per vertex: a third of the area of the incident triangles (sums to the surface area).
std::vector<double> vertex_areas(const TriangleMesh& mesh);

// The top of the diaphragm's dome: the diaphragmatic vertices (by label) whose smoothed normal
// lies within 30 degrees of straight down (where the diaphragm is nearly horizontal) and within
// `depth_m` below the highest of them. Per vertex; all false when the surface has no dome.
std::vector<bool> dome_top_vertices(const TriangleMesh& mesh, const SurfaceRegions& regions, double depth_m = 0.01);

// How the diaphragm's load concentrates at its dome (the diaphragm moves as a piston, its rim on
// the ribs barely): times a profile of the horizontal distance r (across `up`) from the
// area-weighted centre of the dome's top (dome_top_vertices), 1 inside `radius_m - falloff_m`,
// `rim` beyond `radius_m + falloff_m`, a smooth step between; then scaled so that the diaphragm's
// total load is unchanged. radius 0: no profile. With `area_m2` the radius is the lung's own:
// the distance within which the diaphragm (area times its region weight) covers `area_m2`, so
// that the same area moves with the dome on a small diaphragm as on a wide one; a diaphragm
// smaller than `area_m2` has no profile.
struct DomeLoad {
  double radius_m = 0.0;
  double area_m2 = 0.0;  // > 0: the radius from this area (radius_m is then ignored)
  double falloff_m = 0.02;
  double rim = 1.0;  // the factor far from the dome, in [0, 1]
};

// Per vertex: a load (the pressure drive of the field) blended from one value per region,
// f_i = sum_r w_ir load_r, with the diaphragmatic term times max(0, -n_i.up): the diaphragm
// drives, most at its dome (normal straight down), least at its rim, where it lies on the ribs
// (the zone of apposition); and times the dome profile above. Throws ValueError for a negative
// radius, a falloff <= 0 or a rim outside [0, 1].
std::vector<double> regional_load(const TriangleMesh& mesh, const SurfaceRegions& regions,
                                  const std::array<double, kRegionCount>& load, const DomeLoad& dome = {});

// The displacement directions of the anatomical field, per vertex, unit length: a blend with
// the region weights of
//   apex, mediastinal  the smoothed normal (their moduli keep them nearly still)
//   costal             the horizontal part of the smoothed normal (the rib cage moves out)
//   diaphragmatic      -up (the diaphragm descends)
// with the normals smoothed at `sigma` (mesh units). Every part is a smooth field in space.
std::vector<Eigen::Vector3d> anatomical_directions(const TriangleMesh& mesh, const SurfaceRegions& regions,
                                                   double sigma);
// The same from `smoothed_normal` = smoothed_normals(mesh, sigma), one per vertex (ValueError),
// computed once by a caller whose other rules use it too (field::compute_field).
std::vector<Eigen::Vector3d> anatomical_directions(const TriangleMesh& mesh, const SurfaceRegions& regions,
                                                   const std::vector<Eigen::Vector3d>& smoothed_normal);

}  // namespace pneuma::mesh
