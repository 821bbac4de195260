// The realistic field read through a fine surface's proxy (mesh/geometry/surface_proxy.h, #50)
// gives the same bits at any thread count: the geometry computed beside the solve, the proxy's
// normals, the thin lung's rule over the proxy and its transfer. In the tsan suite too.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <memory>

#include "pneuma/field/field.h"
#include "pneuma/mesh/anatomy/phantom.h"

using namespace pneuma;

namespace {

TEST(ProxyThreads, TheRealisticFieldThroughAProxyIsTheSameBitsOnOneThreadAndOnFour) {
  mesh::PhantomOptions fine;
  fine.lung = mesh::Lung::right;
  fine.edge_length_m = 1.4e-3;
  const mesh::TriangleMesh m = mesh::make_lung_phantom(fine);
  field::FieldOptions options;
  options.direction = field::DirectionKind::anatomical;
  options.magnitude_smoothing = 3e-3;
  options.heart.descent = 0.6;
  options.regions = std::make_shared<const mesh::SurfaceRegions>(mesh::find_regions(m));
  options.proxy = mesh::proxy_for(m);
  ASSERT_TRUE(options.proxy);
  const std::vector<double> modulus(m.vertices.size(), 1e3);
  std::vector<std::vector<Eigen::Vector3d>> u;
  for (const int threads : {1, 4}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
    u.push_back(field::compute_field(m, modulus, options).unit_displacement);
  }
  ASSERT_EQ(u[0].size(), m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) ASSERT_EQ(u[0][i], u[1][i]) << "vertex " << i;
}

}  // namespace
