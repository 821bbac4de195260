#pragma once
// Images pulled back through a pull-back DVF v (dvf.h): out(x) = in(x + v(x)) at every voxel
// centre x of the DVF's grid, whatever the input's own grid (both in LPS metres).
#include <limits>
#include <vector>

#include "pneuma/mesh/labels/labels.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/grid.h"

namespace pneuma::voxels {

// A scalar image (a CT in Hounsfield units) with its grid.
struct Image {
  Grid grid;
  std::vector<float> values;  // i fastest
};

// Air: what a warped CT shows where x + v(x) falls outside the input image.
inline constexpr float kOutsideHu = -1024.0f;

// Labels kept, never blended: out(x) = labels(round(ijk(x + v(x)))), the nearest voxel (index
// coordinates rounded half up); 0 where that voxel is outside the label map. The result is on
// the DVF's grid, with the input's segments.
//
// With `lung_labels` (per lung of the DVF: its label values), a voxel inside deformed lung i
// whose nearest voxel holds none of lung i's labels (x + v(x) lies in the lung's rest mesh, but
// within half a voxel of its edge, nearer to a voxel outside) takes the nearest of lung i's
// labels among the eight voxels around x + v(x), where there is one. Without it, a growing lung
// loses part of that rim (5 % of a 20 mm ball on a 1 mm grid); with it the warped lung's voxels
// are those of the deformed mesh.
mesh::LabelMap warp_labels(const mesh::LabelMap& labels, const DisplacementField& pullback,
                           const std::vector<std::vector<int>>* lung_labels = nullptr);
// The same into `out` (its storage reused).
void warp_labels(const mesh::LabelMap& labels, const DisplacementField& pullback, mesh::LabelMap& out,
                 const std::vector<std::vector<int>>* lung_labels = nullptr);

// Trilinear interpolation of the voxel values at x + v(x); `outside` where that point is more
// than half a voxel outside the image (between the outer voxel centres and the image's edge the
// edge value is kept).
Image warp_image(const Image& image, const DisplacementField& pullback, float outside = kOutsideHu);
// The same into `out` (its storage reused).
void warp_image(const Image& image, const DisplacementField& pullback, Image& out, float outside = kOutsideHu);

}  // namespace pneuma::voxels
