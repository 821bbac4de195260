// The realistic field of a fine surface, its tissue inputs read through the surface's proxy
// (mesh/geometry/surface_proxy.h, #50), against the same field read from every vertex.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>

#include "pneuma/field/field.h"
#include "pneuma/field/tissue.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/scenario/tissue_config.h"
#include "test_support.h"

using namespace pneuma;
using namespace pneuma::field;

namespace {

// The proxy that is the mesh itself: each vertex its own group, the same triangles. Every rule
// read through it reads the mesh (the normals' grid is smoothed_normals' at cells this small, the
// transfer the identity: no neighbour within two cells), so the field is the one without a proxy.
std::shared_ptr<const mesh::SurfaceProxy> identity_proxy(const mesh::TriangleMesh& m) {
  auto proxy = std::make_shared<mesh::SurfaceProxy>();
  proxy->mesh = m;
  proxy->fine_vertex.resize(m.vertices.size());
  std::iota(proxy->fine_vertex.begin(), proxy->fine_vertex.end(), 0U);
  proxy->group = proxy->fine_vertex;
  proxy->cell_m = 1e-9;
  return proxy;
}

TEST(ProxyField, TheRealisticFieldOfAFinePhantomIsWithinAFewPercentOfTheFieldReadFromEveryVertex) {
  mesh::PhantomOptions fine;
  fine.lung = mesh::Lung::right;
  fine.edge_length_m = 1.2e-3;
  const mesh::TriangleMesh m = mesh::make_lung_phantom(fine);
  ASSERT_LT(mesh::mean_edge_length(m), mesh::kProxyBelowEdgeM);
  const Tissue upright = scenario::load_tissue(test::source_dir() / "configs" / "tissue" / "healthy-upright.yaml");

  const TissueFieldInputs through_proxy = tissue_field_inputs(m, upright);
  ASSERT_TRUE(through_proxy.options.proxy);  // built once, for the regions and the field
  EXPECT_LT(through_proxy.options.proxy->mesh.vertices.size(), m.vertices.size() / 2);

  // The same inputs read from every vertex: the regions, the load and the moduli from them.
  TissueFieldInputs every_vertex = through_proxy;
  mesh::RegionOptions region_options;
  region_options.axes = body_axes(upright);
  every_vertex.options.regions = std::make_shared<const mesh::SurfaceRegions>(mesh::find_regions(m, region_options));
  every_vertex.options.load =
      mesh::regional_load(m, *every_vertex.options.regions, *upright.regional_load, upright.dome_load);
  const std::vector<double> factor = load_gravity_factor(upright, m);
  for (std::size_t i = 0; i < factor.size(); ++i) every_vertex.options.load[i] *= factor[i];
  every_vertex.shear_modulus_pa = shear_modulus_per_vertex(upright, m, every_vertex.options.regions.get());
  every_vertex.options.proxy = identity_proxy(m);

  const ElastostaticField a = compute_field(m, through_proxy);
  const ElastostaticField b = compute_field(m, every_vertex);
  double worst = 0.0, largest = 0.0, mean = 0.0;
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const double d = (a.unit_displacement[i] - b.unit_displacement[i]).norm();
    worst = std::max(worst, d);
    mean += d / static_cast<double>(m.vertices.size());
    largest = std::max(largest, b.unit_displacement[i].norm());
  }
  // Measured 0.5-0.7 % at 346k and 1M vertices of this phantom (BENCHMARKS.md, #50).
  EXPECT_LT(worst / largest, 0.02);
  EXPECT_LT(mean / largest, 0.002);
  EXPECT_GT(worst, 0.0);  // the proxy was read
}

TEST(ProxyField, AProxyOfAnotherSurfaceIsRefused) {
  mesh::PhantomOptions coarse;
  coarse.lung = mesh::Lung::right;
  const mesh::TriangleMesh m = mesh::make_lung_phantom(coarse);
  const Tissue upright = scenario::load_tissue(test::source_dir() / "configs" / "tissue" / "healthy-upright.yaml");
  TissueFieldInputs inputs = tissue_field_inputs(m, upright);
  EXPECT_FALSE(inputs.options.proxy);  // 4 mm edges: the surface is read as it is
  inputs.options.proxy = identity_proxy(mesh::make_icosphere(0.05, 2));
  EXPECT_THROW(compute_field(m, inputs), ValueError);
}

}  // namespace
