#include "pneuma/render/camera.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace pneuma::render {

bool parse_camera_preset(std::string_view name, CameraPreset& preset) {
  if (name == "anterior") preset = CameraPreset::anterior;
  else if (name == "posterior") preset = CameraPreset::posterior;
  else if (name == "left" || name == "left-lateral" || name == "lateral") preset = CameraPreset::left_lateral;
  else if (name == "right" || name == "right-lateral") preset = CameraPreset::right_lateral;
  else if (name == "oblique") preset = CameraPreset::oblique;
  else return false;
  return true;
}

std::string_view camera_preset_name(CameraPreset preset) {
  switch (preset) {
    case CameraPreset::anterior: return "anterior";
    case CameraPreset::posterior: return "posterior";
    case CameraPreset::left_lateral: return "left";
    case CameraPreset::right_lateral: return "right";
    case CameraPreset::oblique: return "oblique";
  }
  return "anterior";
}

namespace {

// Unit vector from the target towards the eye.
Eigen::Vector3d eye_direction(CameraPreset preset) {
  switch (preset) {
    case CameraPreset::anterior: return {0, -1, 0};
    case CameraPreset::posterior: return {0, 1, 0};
    case CameraPreset::left_lateral: return {1, 0, 0};
    case CameraPreset::right_lateral: return {-1, 0, 0};
    case CameraPreset::oblique: {
      const double azimuth = std::numbers::pi / 4, elevation = 20.0 * std::numbers::pi / 180.0;
      return {std::sin(azimuth) * std::cos(elevation), -std::cos(azimuth) * std::cos(elevation), std::sin(elevation)};
    }
  }
  return {0, -1, 0};
}

}  // namespace

Camera frame_camera(CameraPreset preset, const std::array<Eigen::Vector3d, 2>& bounds, double aspect, double fov_y_deg,
                    double margin) {
  Eigen::Vector3d lo = bounds[0], hi = bounds[1];
  if (!(lo.array() <= hi.array()).all()) {  // an empty mesh: frame a 10 cm box at the origin
    lo = Eigen::Vector3d::Constant(-0.05);
    hi = Eigen::Vector3d::Constant(0.05);
  }
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const Eigen::Vector3d back = eye_direction(preset);  // camera z axis (it looks along -back)
  const Eigen::Vector3d right = Eigen::Vector3d::UnitZ().cross(back).normalized();
  const Eigen::Vector3d up = back.cross(right);
  const double tan_y = std::tan(0.5 * fov_y_deg * std::numbers::pi / 180.0) / margin;
  const double tan_x = tan_y * aspect;
  // A corner at (x, y, z) in camera axes relative to the centre is inside the view when the
  // eye, at distance d along `back`, sees it under |x| / (d - z) <= tan_x and likewise y.
  double distance = 0.0, radius = 0.5 * (hi - lo).norm();
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d p((corner & 1) ? hi.x() : lo.x(), (corner & 2) ? hi.y() : lo.y(),
                            (corner & 4) ? hi.z() : lo.z());
    const Eigen::Vector3d q = p - centre;
    const double z = q.dot(back);
    distance = std::max({distance, z + std::abs(q.dot(right)) / tan_x, z + std::abs(q.dot(up)) / tan_y});
  }
  radius = std::max(radius, 1e-6);
  Camera camera;
  camera.fov_y_deg = fov_y_deg;
  camera.target = centre;
  camera.eye = centre + distance * back;
  camera.up = up;
  // Depth range with room for frames beyond the framed range.
  camera.near_m = std::max(distance - 2.0 * radius, 0.02 * distance);
  camera.far_m = distance + 2.0 * radius;
  return camera;
}

Eigen::Matrix4d view_matrix(const Camera& camera) {
  const Eigen::Vector3d back = (camera.eye - camera.target).normalized();
  const Eigen::Vector3d right = camera.up.cross(back).normalized();
  const Eigen::Vector3d up = back.cross(right);
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<1, 3>(0, 0) = right.transpose();
  m.block<1, 3>(1, 0) = up.transpose();
  m.block<1, 3>(2, 0) = back.transpose();
  m(0, 3) = -right.dot(camera.eye);
  m(1, 3) = -up.dot(camera.eye);
  m(2, 3) = -back.dot(camera.eye);
  return m;
}

Eigen::Matrix4d projection_matrix(const Camera& camera, double aspect) {
  // gluPerspective.
  const double f = 1.0 / std::tan(0.5 * camera.fov_y_deg * std::numbers::pi / 180.0);
  const double n = camera.near_m, fa = camera.far_m;
  Eigen::Matrix4d m = Eigen::Matrix4d::Zero();
  m(0, 0) = f / aspect;
  m(1, 1) = f;
  m(2, 2) = (fa + n) / (n - fa);
  m(2, 3) = 2.0 * fa * n / (n - fa);
  m(3, 2) = -1.0;
  return m;
}

}  // namespace pneuma::render
