#pragma once
// Cameras for lung renders, framed from the mesh bounds.
//
// Patient coordinates follow DICOM's LPS convention: +x towards the patient's left, +y
// posterior, +z superior (up in every preset). The anterior view looks at the patient's front,
// so the patient's left appears on the image's right, as on a chest radiograph.
#include <Eigen/Core>
#include <array>
#include <string>
#include <string_view>

namespace pneuma::render {

enum class CameraPreset {
  anterior,       // from the front (-y), looking posterior
  posterior,      // from the back (+y)
  left_lateral,   // from the patient's left (+x)
  right_lateral,  // from the patient's right (-x)
  oblique,        // left anterior oblique: 45 degrees between anterior and left, 20 degrees above
};

// "anterior", "posterior", "left", "right", "oblique" (also "left-lateral", "right-lateral",
// "lateral" = "left"). Returns false for anything else.
bool parse_camera_preset(std::string_view name, CameraPreset& preset);
std::string_view camera_preset_name(CameraPreset preset);

// A perspective camera in patient coordinates (metres).
struct Camera {
  Eigen::Vector3d eye = {0, -1, 0};
  Eigen::Vector3d target = {0, 0, 0};
  Eigen::Vector3d up = {0, 0, 1};
  double fov_y_deg = 30.0;
  double near_m = 0.01;
  double far_m = 10.0;
};

// The camera of `preset` that fits the box `bounds` ({min, max}) in an image of
// `aspect` = width / height with `margin` (1.1 = 10 % free space around the tightest fit):
// every corner of the box lies inside the view, the box centre on the optical axis.
Camera frame_camera(CameraPreset preset, const std::array<Eigen::Vector3d, 2>& bounds, double aspect,
                    double fov_y_deg = 30.0, double margin = 1.1);

// Column-major 4x4 matrices (OpenGL convention) in double precision.
Eigen::Matrix4d view_matrix(const Camera& camera);
Eigen::Matrix4d projection_matrix(const Camera& camera, double aspect);

}  // namespace pneuma::render
