#pragma once
// The built-in lung phantom: adult left and right lungs at functional residual capacity,
// generated at any resolution, so every scenario runs with no external data.
//
// Coordinate frame: DICOM patient coordinates (LPS), in metres:
//   +x towards the patient's left, +y posterior, +z superior (up, apex at the top).
// (x left, y anterior, z up would be a left-handed frame, in which "counter-clockwise seen
// from outside" would turn inward; LPS is right-handed and is what CT segmentations use.)
// Origin: x = 0 on the mid-sagittal plane, y = 0 midway between the front and the back of the
// lung bases, z = 0 at the lowest point of the bases (the posterior costophrenic recesses).
// The right lung lies at x < 0, the left at x > 0; apexes at z = 0.245 (right) and 0.25 m (left).
// Volumes at functional residual capacity: about 1.4 L (right) and 1.2 L (left).
//
// Shape (per lung, an implicit function, see phantom.cpp): a tapering superelliptic body
// (curved costal surface, thin anterior border, thick rounded posterior border, rounded apex
// leaning medially and posteriorly), cut by a flattened medial (mediastinal) surface, a
// concave diaphragmatic base over the dome (higher on the right, over the liver), and the
// heart, which carves the cardiac impression into both medial surfaces and the cardiac notch
// into the anterior border of the left lung.
//
// Mesh: the surface is star-shaped around a point inside each lung, so it is sampled along
// the rays through the vertices of a geodesic sphere (Class I icosahedral, frequency n:
// 20 n^2 triangles, 10 n^2 + 2 vertices), then relaxed tangentially a few times (each vertex
// towards the mean of its neighbours, projected back along its ray) to even out edge lengths.
// Every triangle stays positively oriented as seen from the centre, which makes the surface
// closed, manifold, free of self-intersections and outward oriented by construction.
// Deterministic: the same options give the same vertices and triangles, bit for bit.
#include <cstddef>

#include "pneuma/core/error.h"
#include "pneuma/mesh/anatomy/lung.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

struct PhantomOptions {
  std::optional<Lung> lung = kBothLungs;  // one lung, or both: two closed components, right lung first
  double edge_length_m = 4e-3;            // mean edge length aimed at
  int relaxation_passes = 4;
};
inline const PhantomOptions kDefaultPhantom{};

// The geodesic frequency n for one lung at this edge length: the n for which 20 n^2 equilateral
// triangles of edge h cover the lung's area A, i.e. n = round(sqrt(A / (5 sqrt(3) h^2))),
// at least 4. The triangle count is then exactly 20 n^2 per lung.
int phantom_frequency(Lung lung, double edge_length_m);

// The count that edge length predicts before rounding n: 4 A / (sqrt(3) h^2) per lung (the
// area over the area of one equilateral triangle), summed over the lungs generated.
double predicted_phantom_triangles(std::optional<Lung> lung, double edge_length_m);

// The point inside the lung from which the surface is star-shaped (right or left only): every
// triangle of the phantom is positively oriented as seen from it (det(a-c, b-c, c'-c) > 0).
Eigen::Vector3d phantom_centre(Lung lung);

// Throws ValueError for a target edge that is not positive and finite, or one
// so small that the mesh would pass 2^31 triangles.
TriangleMesh make_lung_phantom(const PhantomOptions& options = kDefaultPhantom);

}  // namespace pneuma::mesh
