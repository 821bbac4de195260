#pragma once
// Shared by the runner tests (runner_test.cpp, trace_run_test.cpp, report_test.cpp, tracking_test.cpp).
#include <filesystem>

#include <Eigen/Core>

#include "pneuma/image/label_map.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/voxels/voxel_io.h"

namespace pneuma::test {

// Signed-tetrahedron volume of a mesh file in metres, read back with the mesh reader: an oracle
// independent of the engine's volume cubic.
inline double file_volume(const std::filesystem::path& p) {
  const auto m = mesh::read_mesh(p);  // in the unit the file records (frames: mm)
  double six = 0.0;
  for (const auto& t : m.triangles) six += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]]));
  return six / 6.0;
}

// A 15 mm ball mask (label 1) centred at `centre` (metres, LPS) on a 24^3 grid of 1.5 mm voxels,
// written to `path` (a target for voxels.structures) and returned.
inline image::LabelMap write_ball_mask(const std::filesystem::path& path, const Eigen::Vector3d& centre) {
  image::LabelMap ball;
  ball.size = {24, 24, 24};
  ball.ijk_to_lps = Eigen::Matrix4d::Identity();
  ball.ijk_to_lps.topLeftCorner<3, 3>() *= 1.5e-3;
  ball.ijk_to_lps.block<3, 1>(0, 3) = centre - Eigen::Vector3d::Constant(1.5e-3 * 11.5);
  ball.labels.resize(ball.voxel_count());
  for (std::size_t k = 0; k < 24; ++k)
    for (std::size_t j = 0; j < 24; ++j)
      for (std::size_t i = 0; i < 24; ++i) {
        const Eigen::Vector3d x = (ball.ijk_to_lps * Eigen::Vector4d(static_cast<double>(i), static_cast<double>(j),
                                                                     static_cast<double>(k), 1.0))
                                      .head<3>();
        ball.labels[i + 24 * (j + 24 * k)] = (x - centre).norm() <= 15e-3;
      }
  voxels::write_label_map(path, ball);
  return ball;
}

}  // namespace pneuma::test
