// Anatomical regions, smoothed normals and the motion summary, against geometric oracles.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <limits>
#include <map>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>

#include "mesh_fixture.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/anatomy/motion_summary.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/anatomy/regions.h"

namespace pneuma::mesh {
namespace {

TriangleMesh phantom(Lung lung, double edge = 6e-3) {
  PhantomOptions o;
  o.lung = lung;
  o.edge_length_m = edge;
  return make_lung_phantom(o);
}

// The mirror image through the mid-sagittal plane x = 0 (orientation kept outward).
TriangleMesh mirrored(TriangleMesh m) {
  for (auto& v : m.vertices) v.x() = -v.x();
  for (auto& t : m.triangles) std::swap(t[1], t[2]);
  return m;
}

TEST(Regions, PhantomSidesAreFoundFromTheGeometry) {
  EXPECT_EQ(find_regions(phantom(Lung::right)).side, Lung::right);
  EXPECT_EQ(find_regions(phantom(Lung::left)).side, Lung::left);
  // The right lung's medial face looks to the patient's left (+x in LPS).
  EXPECT_GT(find_regions(phantom(Lung::right)).medial.x(), 0.99);
  EXPECT_LT(find_regions(phantom(Lung::left)).medial.x(), -0.99);
}

TEST(Regions, WeightsArePartitionOfUnityAndAreasAddUp) {
  const TriangleMesh m = phantom(Lung::right);
  const SurfaceRegions r = find_regions(m);
  const std::vector<double> area = vertex_areas(m);
  std::array<double, kRegionCount> region_area{};
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    double sum = 0.0;
    for (double w : r.weight[i]) {
      EXPECT_GE(w, 0.0);
      sum += w;
    }
    EXPECT_NEAR(sum, 1.0, 1e-12);
    region_area[static_cast<std::size_t>(r.label[i])] += area[i];
    EXPECT_EQ(r.weight[i][static_cast<std::size_t>(r.label[i])],
              *std::max_element(r.weight[i].begin(), r.weight[i].end()));
  }
  EXPECT_NEAR(std::accumulate(region_area.begin(), region_area.end(), 0.0), surface_area(m), 1e-12);
  for (double a : region_area) EXPECT_GT(a, 0.03 * surface_area(m));  // every region is there
}

TEST(Regions, DownwardNormalsAreDiaphragmaticAndTheTopIsApex) {
  for (Lung lung : {Lung::right, Lung::left}) {
    const TriangleMesh m = phantom(lung);
    const SurfaceRegions r = find_regions(m);
    int checked = 0;
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
      if (r.normal[i].z() < -0.95 && r.height[i] < 0.4) {
        EXPECT_EQ(r.label[i], Region::diaphragmatic) << i;
        ++checked;
      }
      if (r.height[i] > 0.95) {
        EXPECT_EQ(r.label[i], Region::apex) << i;
      }
      // A steep face looking straight at the midline, mid-height: mediastinal.
      if (r.normal[i].dot(r.medial) > 0.9 && r.height[i] > 0.4 && r.height[i] < 0.7) {
        EXPECT_EQ(r.label[i], Region::mediastinal) << i;
      }
    }
    EXPECT_GT(checked, 3);
  }
}

TEST(Regions, MirroredLungGetsMirroredLabels) {
  const TriangleMesh right = phantom(Lung::right);
  const SurfaceRegions a = find_regions(right), b = find_regions(mirrored(right));
  EXPECT_EQ(a.side, Lung::right);
  EXPECT_EQ(b.side, Lung::left);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.label.size(); ++i) differ += a.label[i] != b.label[i];
  // The grid of the blur is not mirror symmetric: a few border vertices may flip.
  EXPECT_LE(differ, a.label.size() / 200);
}

TEST(Regions, SphereBottomIsDiaphragmaticTopIsApex) {
  const TriangleMesh s = make_icosphere(0.1, 4);
  RegionOptions o;
  o.side = Lung::right;
  const SurfaceRegions r = find_regions(s, o);
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    const Eigen::Vector3d n = s.vertices[i].normalized();
    if (n.z() < -0.9) {
      EXPECT_EQ(r.label[i], Region::diaphragmatic);
    }
    if (n.z() > 0.9) {
      EXPECT_EQ(r.label[i], Region::apex);
    }
    if (n.x() > 0.97) {                            // steeper than the diaphragmatic border (-n.up > 0.25)
      EXPECT_EQ(r.label[i], Region::mediastinal);  // right lung: medial is +x
    }
    if (n.x() < -0.97) {
      EXPECT_EQ(r.label[i], Region::costal);
    }
  }
}

TEST(SmoothedNormals, SphereNormalsAreRadial) {
  const TriangleMesh s = make_icosphere(0.1, 4);
  const auto n = smoothed_normals(s, 0.02);
  for (std::size_t i = 0; i < n.size(); ++i) EXPECT_GT(n[i].dot(s.vertices[i].normalized()), 0.999);
  EXPECT_THROW(smoothed_normals(s, 0.0), pneuma::ValueError);
}

TEST(SmoothedNormals, TwoLipsOfANarrowCreaseMoveTogether) {
  // Two parallel plates 4 mm apart (a cube squashed) seen through a 20 mm blur: the facing
  // faces' normals are opposite, their smoothed normals nearly the same.
  TriangleMesh thin = make_icosphere(0.05, 4);
  for (auto& v : thin.vertices) v.z() *= 0.04;
  const auto raw = vertex_normals(thin);
  const auto smooth = smoothed_normals(thin, 0.02);
  // Vertices near the rim: raw normals radial-horizontal, smooth ones too; in the middle the
  // top and bottom differ in raw normal by 180 degrees but both blur to nearly the same field.
  double worst_raw = 1.0, worst_smooth = 1.0;
  for (std::size_t i = 0; i < thin.vertices.size(); ++i) {
    for (std::size_t j = 0; j < thin.vertices.size(); ++j) {
      if ((thin.vertices[i] - thin.vertices[j]).norm() > 0.005) continue;
      worst_raw = std::min(worst_raw, raw[i].dot(raw[j]));
      worst_smooth = std::min(worst_smooth, smooth[i].dot(smooth[j]));
    }
  }
  EXPECT_LT(worst_raw, -0.9);
  EXPECT_GT(worst_smooth, worst_raw + 0.5);
}

// Oracles: a constant is kept exactly (the average of equal values); on a flattened sphere
// (two sheets 2 mm apart at its middle) with 0 on the top sheet and 1 on the bottom one, the
// values of vertices close in space (< 3 mm) end up close however far apart along the surface;
// a blur much smaller than the gap between the sheets keeps them apart.
TEST(BlurredInSpace, KeepsConstantsAndJoinsTheLipsOfAThinGap) {
  TriangleMesh thin = make_icosphere(0.05, 4);
  for (auto& v : thin.vertices) v.z() *= 0.02;
  const std::vector<double> constant(thin.vertices.size(), 0.37);
  for (double b : blurred_in_space(thin, constant, 0.004)) EXPECT_NEAR(b, 0.37, 1e-12);
  std::vector<double> sheet(thin.vertices.size());
  for (std::size_t i = 0; i < sheet.size(); ++i) sheet[i] = thin.vertices[i].z() > 0.0 ? 0.0 : 1.0;
  auto widest_jump = [&](const std::vector<double>& v) {
    double worst = 0.0;
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (std::hypot(thin.vertices[i].x(), thin.vertices[i].y()) > 0.03) continue;  // the flat middle
      for (std::size_t j = 0; j < v.size(); ++j) {
        if ((thin.vertices[i] - thin.vertices[j]).norm() < 0.003) worst = std::max(worst, std::abs(v[i] - v[j]));
      }
    }
    return worst;
  };
  EXPECT_EQ(widest_jump(sheet), 1.0);
  EXPECT_LT(widest_jump(blurred_in_space(thin, sheet, 0.004)), 0.2);
  EXPECT_GT(widest_jump(blurred_in_space(thin, sheet, 0.0003)), 0.9);
  EXPECT_THROW(blurred_in_space(thin, sheet, 0.0), pneuma::ValueError);
  EXPECT_THROW(blurred_in_space(thin, std::vector<double>(3, 1.0), 0.004), pneuma::ValueError);
  EXPECT_TRUE(blurred_in_space(TriangleMesh{}, {}, 0.004).empty());
}

TEST(MotionSummary, SweptVolumesAddUpToTheVolumeChange) {
  const TriangleMesh m = phantom(Lung::left, 8e-3);
  std::vector<Eigen::Vector3d> d(m.vertices.size());
  for (std::size_t i = 0; i < d.size(); ++i) {
    const double x = static_cast<double>(i);
    d[i] = 0.01 * Eigen::Vector3d(std::sin(3.0 * x), std::cos(7.0 * x), std::sin(11.0 * x + 1));
  }
  const auto swept = swept_volumes(m, d);
  TriangleMesh moved = m;
  for (std::size_t i = 0; i < d.size(); ++i) moved.vertices[i] += d[i];
  EXPECT_NEAR(std::accumulate(swept.begin(), swept.end(), 0.0), enclosed_volume(moved) - enclosed_volume(m),
              1e-12 * enclosed_volume(m));
}

TEST(MotionSummary, UniformDilationSharesFollowAreasAndDoNotDependOnTheOrigin) {
  // Every vertex of a sphere moves out by the same amount: each region's share of the volume
  // change is its share of the area (to the discretisation), wherever the sphere lies.
  TriangleMesh s = make_icosphere(0.1, 4);
  RegionOptions o;
  o.side = Lung::right;
  const SurfaceRegions r = find_regions(s, o);
  std::vector<Eigen::Vector3d> u(s.vertices.size());
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = s.vertices[i].normalized();
  const MotionSummary a = summarize_motion(s, u, 0.002, r);
  const double total_area = surface_area(s);
  for (Region k : kRegions) {
    const auto& m = a.region[static_cast<std::size_t>(k)];
    EXPECT_NEAR(m.volume_share, m.area_m2 / total_area, 0.01) << region_name(k);
    EXPECT_NEAR(m.magnitude_mean_m, 0.002, 1e-12);
  }
  for (auto& v : s.vertices) v += Eigen::Vector3d(1.0, -2.0, 0.5);
  const MotionSummary b = summarize_motion(s, u, 0.002, r);
  for (Region k : kRegions)
    EXPECT_NEAR(a.region[static_cast<std::size_t>(k)].volume_share, b.region[static_cast<std::size_t>(k)].volume_share,
                1e-9);
  // A pure downward translation: the diaphragm's mean caudal displacement is the translation.
  std::vector<Eigen::Vector3d> down(s.vertices.size(), Eigen::Vector3d(0, 0, -1));
  const MotionSummary c = summarize_motion(s, down, 0.005, r);
  EXPECT_NEAR(c.region[static_cast<std::size_t>(Region::diaphragmatic)].caudal_mean_m, 0.005, 1e-12);
  EXPECT_NEAR(c.dome_top_caudal_m, 0.005, 1e-12);
  EXPECT_NEAR(c.volume_change_m3, 0.0, 1e-15);
}

TEST(RegionalLoad, BlendsTheRegionsLoadsAndDrivesTheDiaphragmByItsDownwardNormal) {
  const TriangleMesh s = make_icosphere(0.1, 4);
  RegionOptions o;
  o.side = Lung::right;
  const SurfaceRegions r = find_regions(s, o);
  const std::array<double, kRegionCount> load{0.1, 0.2, 1.0, 0.05};  // apex, costal, diaphragmatic, mediastinal
  const std::vector<double> f = regional_load(s, r, load);
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    const auto& w = r.weight[i];
    const double expected = 0.1 * w[0] + 0.2 * w[1] + 1.0 * w[2] * std::max(0.0, -r.normal[i].z()) + 0.05 * w[3];
    EXPECT_NEAR(f[i], expected, 1e-12) << i;
  }
}

TEST(RegionalLoad, TheDomeProfileMovesTheDiaphragmsDriveInwardAndKeepsItsTotal) {
  // A sphere's lower cap: the dome's top is the ring 30 degrees from the bottom, centred on the
  // z axis, so the profile depends on the distance from the axis. Only the diaphragm is loaded.
  const TriangleMesh s = make_icosphere(0.1, 4);
  RegionOptions o;
  o.side = Lung::right;
  const SurfaceRegions r = find_regions(s, o);
  const std::array<double, kRegionCount> load{0.0, 0.0, 1.0, 0.0};
  const DomeLoad dome{.radius_m = 0.04, .falloff_m = 0.01, .rim = 0.25};
  const std::vector<double> plain = regional_load(s, r, load), peaked = regional_load(s, r, load, dome);
  const std::vector<double> area = vertex_areas(s);
  double total_plain = 0.0, total_peaked = 0.0;
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    total_plain += area[i] * plain[i];
    total_peaked += area[i] * peaked[i];
  }
  EXPECT_NEAR(total_peaked, total_plain, 1e-12 * total_plain);
  // Inside radius - falloff the factor is one constant k, beyond radius + falloff it is k * rim,
  // and it falls with the distance between.
  // The centre: the area-weighted mean of the dome's top (checked below), near the axis.
  const std::vector<bool> top = dome_top_vertices(s, r);
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double top_area = 0.0;
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    if (top[i]) {
      centre += area[i] * s.vertices[i];
      top_area += area[i];
    }
  }
  centre /= top_area;
  EXPECT_LT(centre.head<2>().norm(), 1e-3);
  std::vector<std::pair<double, double>> ratio;  // (horizontal distance from the centre, peaked / plain)
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    if (plain[i] > 1e-6) ratio.emplace_back((s.vertices[i] - centre).head<2>().norm(), peaked[i] / plain[i]);
  }
  std::sort(ratio.begin(), ratio.end());
  const double k = ratio.front().second;
  EXPECT_GT(k, 1.0);
  int inside = 0, outside = 0;
  for (std::size_t j = 0; j < ratio.size(); ++j) {
    const auto [distance, factor] = ratio[j];
    if (distance < 0.03 - 1e-9) {
      EXPECT_NEAR(factor, k, 1e-12 * k);
      ++inside;
    }
    if (distance > 0.05 + 1e-9) {
      EXPECT_NEAR(factor, 0.25 * k, 1e-12 * k);
      ++outside;
    }
    if (j > 0) {
      EXPECT_LE(factor, ratio[j - 1].second + 1e-12) << distance;
    }
  }
  EXPECT_GT(inside, 10);
  EXPECT_GT(outside, 10);
  // The dome's top: diaphragmatic, normal within 30 degrees of straight down, within 10 mm of the highest such vertex.
  double highest = -1.0;
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    if (r.label[i] == Region::diaphragmatic && -r.normal[i].z() >= std::cos(std::numbers::pi / 6))
      highest = std::max(highest, s.vertices[i].z());
  }
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    const bool expected = r.label[i] == Region::diaphragmatic && -r.normal[i].z() >= std::cos(std::numbers::pi / 6) &&
                          s.vertices[i].z() >= highest - 0.01;
    EXPECT_EQ(top[i], expected) << i;
  }
  EXPECT_THROW(regional_load(s, r, load, {.radius_m = -0.01}), pneuma::ValueError);
  EXPECT_THROW(regional_load(s, r, load, {.radius_m = 0.04, .falloff_m = 0.0}), pneuma::ValueError);
  EXPECT_THROW(regional_load(s, r, load, {.radius_m = 0.04, .falloff_m = 0.01, .rim = 1.5}), pneuma::ValueError);
}

}  // namespace
}  // namespace pneuma::mesh

namespace pneuma::mesh {
namespace {

// The dome profile sized by area (one preset for every lung): the radius is where the
// diaphragm's area, counted outward from the dome's centre, reaches the given area. On a sphere
// of radius R the cap within horizontal distance rho of the axis has area 2 pi R (R - sqrt(R^2 -
// rho^2)): asking for the cap of rho = 40 mm gives the profile of a 40 mm radius, to within the
// mesh's spacing; asking for more than the whole diaphragm leaves the load as it is.
TEST(RegionalLoad, TheDomeProfileSizedByAreaTakesItsRadiusFromTheDiaphragmsArea) {
  const double radius = 0.1;
  const TriangleMesh s = make_icosphere(radius, 5);
  RegionOptions o;
  o.side = Lung::right;
  const SurfaceRegions r = find_regions(s, o);
  const std::array<double, kRegionCount> load{0.0, 0.0, 1.0, 0.0};
  const std::vector<double> plain = regional_load(s, r, load);
  EXPECT_EQ(regional_load(s, r, load, {.area_m2 = 1.0, .falloff_m = 0.01, .rim = 0.25}), plain);
  // The lower cap is wholly diaphragmatic out to rho = 40 mm (checked, so that the cap's area is
  // the diaphragm's there).
  const std::vector<double> area = vertex_areas(s);
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    if (s.vertices[i].z() < 0.0 && s.vertices[i].head<2>().norm() < 0.045) {
      ASSERT_EQ(r.weight[i][static_cast<std::size_t>(Region::diaphragmatic)], 1.0) << i;
    }
  }
  const double rho = 0.04;
  const double cap_m2 = 2.0 * std::numbers::pi * radius * (radius - std::sqrt(radius * radius - rho * rho));
  const std::vector<double> by_area = regional_load(s, r, load, {.area_m2 = cap_m2, .falloff_m = 0.01, .rim = 0.25});
  const std::vector<double> by_radius = regional_load(s, r, load, {.radius_m = rho, .falloff_m = 0.01, .rim = 0.25});
  double total = 0.0, difference = 0.0;
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    total += area[i] * by_radius[i];
    difference += area[i] * std::abs(by_area[i] - by_radius[i]);
  }
  EXPECT_GT(total, 0.0);
  // Vertices lie about 5 mm apart: the radius found is within one of them of 40 mm, which moves
  // a little of the load across a 20 mm wide step.
  EXPECT_LT(difference, 0.03 * total);
  EXPECT_THROW(regional_load(s, r, load, {.area_m2 = -1.0}), pneuma::ValueError);
}

TEST(Geometry, SphereMeanCurvatureIsOneOverRadiusAndHullDepthIsZero) {
  const TriangleMesh s = make_icosphere(0.1, 4);
  // Per vertex within 15 % (the barycentric area is rough at the icosahedron's valence-5
  // vertices), the area-weighted mean within 1 %.
  const std::vector<double> h = mean_curvature(s), area = vertex_areas(s);
  double sum = 0.0;
  for (std::size_t i = 0; i < h.size(); ++i) {
    EXPECT_NEAR(h[i], 10.0, 1.5);
    sum += h[i] * area[i];
  }
  EXPECT_NEAR(sum / surface_area(s), 10.0, 0.1);
  std::vector<Eigen::Vector3d> points = s.vertices;
  points.push_back(Eigen::Vector3d::Zero());  // the centre lies ~R below the hull
  const std::vector<double> depth = depth_below_convex_hull(points);
  for (std::size_t i = 0; i < s.vertices.size(); ++i) EXPECT_NEAR(depth[i], 0.0, 1e-12);
  EXPECT_NEAR(depth.back(), 0.1, 0.002);
  // Queries apart from the hull's points: the depth of a point is min over the hull's face
  // planes of (offset - n.x) (a direct loop over every face here), 0 outside.
  const std::vector<Eigen::Vector3d> queries{{0.0, 0.0, 0.05}, {0.03, -0.02, 0.01}, {0.0, 0.0, 0.2}};
  const std::vector<double> queried = depth_below_convex_hull(s.vertices, queries);
  ASSERT_EQ(queried.size(), 3u);
  for (std::size_t q = 0; q < 2; ++q) {
    double direct = std::numeric_limits<double>::infinity();
    for (const auto& t : s.triangles) {  // the icosphere is its own convex hull
      const Eigen::Vector3d n =
          (s.vertices[t[1]] - s.vertices[t[0]]).cross(s.vertices[t[2]] - s.vertices[t[0]]).normalized();
      direct = std::min(direct, n.dot(s.vertices[t[0]]) - n.dot(queries[q]));
    }
    EXPECT_NEAR(queried[q], direct, 1e-12);
  }
  EXPECT_EQ(queried[2], 0.0);
}

TEST(Regions, SameMeshSameBits) {
  PhantomOptions o;
  o.lung = Lung::left;
  o.edge_length_m = 8e-3;
  const TriangleMesh m = make_lung_phantom(o);
  const SurfaceRegions a = find_regions(m), b = find_regions(m);
  EXPECT_EQ(a.label, b.label);
  for (std::size_t i = 0; i < m.vertices.size(); ++i) EXPECT_EQ(a.weight[i], b.weight[i]);
  EXPECT_EQ(anatomical_directions(m, a, 0.02), anatomical_directions(m, b, 0.02));
}

}  // namespace
}  // namespace pneuma::mesh

namespace pneuma::mesh {
namespace {

// The same surface gives the same regions, bit for bit, on every call in one process (CGAL lists
// a hull face's vertices from any corner; the planes must not depend on that). On a sphere the
// two sides tie, so any drift in the hull depths would flip the side and every weight.
TEST(Regions, TheSameSurfaceGivesTheSameBitsOnEveryCall) {
  const TriangleMesh sphere = make_icosphere(0.1, 3);
  const SurfaceRegions first = find_regions(sphere);
  for (int call = 0; call < 10; ++call) {
    const SurfaceRegions again = find_regions(sphere);
    ASSERT_EQ(again.side, first.side) << call;
    ASSERT_EQ(again.left_face_depth, first.left_face_depth) << call;
    ASSERT_EQ(again.right_face_depth, first.right_face_depth) << call;
    ASSERT_EQ(again.weight, first.weight) << call;
    ASSERT_EQ(again.label, first.label) << call;
  }
}

}  // namespace
}  // namespace pneuma::mesh

namespace pneuma::mesh {
namespace {

// The coarse proxy of the hull (issue #50): one input point per occupied cell, the one farthest
// from the points' mean (checked cell by cell by brute force).
TEST(HullProxy, KeepsOneInputPointPerOccupiedCellTheFarthestFromTheMean) {
  const TriangleMesh s = make_icosphere(0.1, 5);  // 10,242 points
  const double cell = 0.01;
  const std::vector<Eigen::Vector3d> kept = hull_proxy_points(s.vertices, cell);
  const auto box = bounding_box(s.vertices);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : s.vertices) mean += p;
  mean /= static_cast<double>(s.vertices.size());
  auto cell_of = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d c = ((p - box[0]) / cell).array().floor();
    return std::array<long, 3>{static_cast<long>(c.x()), static_cast<long>(c.y()), static_cast<long>(c.z())};
  };
  std::map<std::array<long, 3>, Eigen::Vector3d> farthest;  // per occupied cell
  for (const auto& p : s.vertices) {
    auto [it, added] = farthest.emplace(cell_of(p), p);
    if (!added && (p - mean).squaredNorm() > (it->second - mean).squaredNorm()) it->second = p;
  }
  ASSERT_EQ(kept.size(), farthest.size());
  for (const auto& p : kept) EXPECT_EQ(farthest.at(cell_of(p)), p);
  EXPECT_EQ(hull_proxy_points(s.vertices, 0.0), s.vertices);  // no proxy
}

// Its hull lies inside the whole hull, within the sagitta of a cell's diagonal: on a sphere of
// radius R every point is within d = cell sqrt(3) of a kept one, so the proxy's hull reaches
// within d^2 / (2 R) of the sphere. A point inside is nearer the proxy's hull: its depth below it
// is <= the exact depth, and at most that sagitta less; the surface's points lie on or outside
// both hulls (depth 0).
TEST(HullProxy, DepthsBelowItsHullAreWithinTheSagittaOfTheExactOnes) {
  const TriangleMesh s = make_icosphere(0.1, 6);  // 40,962 points, 1.9 mm apart
  const double cell = 2e-3, bound = 3.0 * cell * cell / (2.0 * 0.1);
  std::vector<Eigen::Vector3d> queries = s.vertices;
  for (double r : {0.0, 0.05, 0.09, 0.099}) queries.emplace_back(r * 0.6, -r * 0.8, 0.0);
  const std::vector<double> exact = depth_below_convex_hull(s.vertices, queries);
  const std::vector<double> proxy = depth_below_convex_hull(hull_proxy_points(s.vertices, cell), queries);
  double largest = 0.0;
  for (std::size_t i = 0; i < queries.size(); ++i) {
    EXPECT_LE(proxy[i], exact[i] + 1e-15);
    if (i < s.vertices.size()) {
      EXPECT_EQ(proxy[i], 0.0);
    }
    largest = std::max(largest, exact[i] - proxy[i]);
  }
  EXPECT_LE(largest, bound);
  EXPECT_GT(largest, 0.0);  // a proxy, not the whole hull
  EXPECT_NEAR(proxy[s.vertices.size()], 0.1, bound + 0.1 * (1.0 - std::cos(std::numbers::pi / 256)));
}

// The side and every weight of the phantom's lungs are the same with the proxy's hull as with the
// hull of every vertex; the deciding depths differ by less than the proxy's bound.
TEST(HullProxy, ThePhantomsSidesAndWeightsAreThoseOfTheExactHull) {
  for (Lung lung : {Lung::right, Lung::left}) {
    const TriangleMesh m = phantom(lung, 2e-3);
    RegionOptions exact_options;
    exact_options.hull_proxy_cell_m = 0.0;
    const SurfaceRegions exact = find_regions(m, exact_options), proxy = find_regions(m);
    EXPECT_EQ(proxy.side, exact.side);
    EXPECT_EQ(proxy.weight, exact.weight);
    EXPECT_NEAR(proxy.left_face_depth, exact.left_face_depth, 0.05e-3);
    EXPECT_NEAR(proxy.right_face_depth, exact.right_face_depth, 0.05e-3);
  }
}

// Oracle: the sum itself, sum_j G(x_i - x_j) A_j v_j / sum_j G(x_i - x_j) A_j over every pair
// of vertices, on a phantom lung (3,400 vertices) with a value that varies on the scale of the
// blur. The grid (spacing sigma, trilinear splat and sample, a Gaussian narrowed by their
// variance) stays within 2 % of the value's range of it; without the narrowing the blur is
// wider and the error larger.
TEST(BlurredInSpace, MatchesTheGaussianSumOverEveryPairOfVertices) {
  const TriangleMesh m = phantom(Lung::right, 3e-3);
  const double sigma = 0.005;
  std::vector<double> value(m.vertices.size());
  for (std::size_t i = 0; i < value.size(); ++i) {
    const Eigen::Vector3d& p = m.vertices[i];
    value[i] = std::sin(p.x() / 0.006) * std::cos(p.y() / 0.008) + std::sin(p.z() / 0.01);
  }
  const auto [lo, hi] = std::minmax_element(value.begin(), value.end());
  const std::vector<double> area = vertex_areas(m);
  const std::vector<double> blurred = blurred_in_space(m, value, sigma);
  double worst = 0.0;
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    double sum = 0.0, weight = 0.0;
    for (std::size_t j = 0; j < m.vertices.size(); ++j) {
      const double g = std::exp(-0.5 * (m.vertices[i] - m.vertices[j]).squaredNorm() / (sigma * sigma)) * area[j];
      sum += g * value[j];
      weight += g;
    }
    worst = std::max(worst, std::abs(blurred[i] - sum / weight));
  }
  std::printf("largest difference from the pairwise sum: %.4f of the range\n", worst / (*hi - *lo));
  EXPECT_LT(worst, 0.02 * (*hi - *lo));
}

// Oracle: blurred_in_space of each value alone. Two and three values blurred at once on one grid
// give each value those bits exactly (the recess rule blurs its values so), with values that
// vanish on parts of the surface (where the one-value grid leaves zero cells out) and values of
// very different size.
TEST(BlurredInSpace, SeveralValuesAtOnceAreEachValueBlurredAloneToTheBit) {
  const TriangleMesh m = phantom(Lung::right, 3e-3);
  const std::vector<double> area = vertex_areas(m);
  std::array<std::vector<double>, 3> alone;
  for (auto& value : alone) value.resize(m.vertices.size());
  std::vector<Eigen::Vector3d> three(m.vertices.size());
  std::vector<Eigen::Vector2d> two(m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const Eigen::Vector3d& p = m.vertices[i];
    alone[0][i] = std::sin(p.x() / 0.006) * std::cos(p.y() / 0.008);
    alone[1][i] = p.z() > 0.0 ? 1e3 * p.z() : 0.0;  // zero over part of the surface
    alone[2][i] = 1e-9 * std::cos(p.z() / 0.01);
    three[i] = {alone[0][i], alone[1][i], alone[2][i]};
    two[i] = {alone[1][i], alone[2][i]};
  }
  for (const double sigma : {0.003, 0.01}) {
    const std::vector<Eigen::Vector3d> blurred_three = blurred_in_space(m, area, three, sigma);
    const std::vector<Eigen::Vector2d> blurred_two = blurred_in_space(m, area, two, sigma);
    for (int c = 0; c < 3; ++c) {
      const std::vector<double> expected = blurred_in_space(m, alone[static_cast<std::size_t>(c)], sigma);
      std::size_t differ = 0;
      for (std::size_t i = 0; i < expected.size(); ++i) {
        differ += blurred_three[i][c] == expected[i] ? 0 : 1;
        if (c > 0) differ += blurred_two[i][c - 1] == expected[i] ? 0 : 1;
      }
      EXPECT_EQ(differ, 0U) << "value " << c << " sigma " << sigma;
    }
  }
  EXPECT_THROW(blurred_in_space(m, std::vector<double>(3, 1.0), three, 0.01), ValueError);
  EXPECT_THROW(blurred_in_space(m, area, three, 0.0), ValueError);
}

// The grid smoothing runs on every thread (lines, rows, z-slabs of the splat): the same bits at
// one, two and four threads, for the smoothed normals, the blur in space and the regions.
TEST(Regions, TheGridSmoothingIsTheSameBitsAtOneTwoAndFourThreads) {
  const TriangleMesh m = phantom(Lung::right, 2e-3);
  std::vector<double> height(m.vertices.size());
  for (std::size_t i = 0; i < height.size(); ++i) height[i] = m.vertices[i].z();
  std::vector<std::vector<Eigen::Vector3d>> normals;
  std::vector<std::vector<double>> blurred;
  std::vector<SurfaceRegions> regions;
  for (int threads : {1, 2, 4}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
    normals.push_back(smoothed_normals(m, 0.02));
    blurred.push_back(blurred_in_space(m, height, 0.003));
    regions.push_back(find_regions(m));
  }
  for (std::size_t k = 1; k < normals.size(); ++k) {
    EXPECT_EQ(normals[k], normals[0]) << k;
    EXPECT_EQ(blurred[k], blurred[0]) << k;
    EXPECT_EQ(regions[k].weight, regions[0].weight) << k;
    EXPECT_EQ(regions[k].left_face_depth, regions[0].left_face_depth) << k;
  }
}

}  // namespace
}  // namespace pneuma::mesh
