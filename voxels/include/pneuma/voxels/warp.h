#pragma once
// Images pulled back through a pull-back DVF v (dvf.h): out(x) = in(x + v(x)) at every voxel
// centre x of the DVF's grid, whatever the input's own grid (both in LPS metres).
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "pneuma/image/label_map.h"
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
// With `rest_lung` (per voxel of `labels`: 0, or 1 + the lung whose rest mesh holds its centre,
// as forward_dvf's `lung` at scale 0 on the label map's grid), a voxel inside deformed lung i
// whose nearest voxel lies outside lung i's rest mesh (x + v(x) is inside the mesh, within half a
// voxel of its edge) takes the label of the nearest of the eight voxels around x + v(x) that lie
// inside it, where there is one; a voxel outside every deformed lung whose nearest voxel lies in
// a rest mesh (the body's tissue, carried by the outside field to the pleura) takes the nearest
// of the eight outside every rest mesh; where none of the eight is on x's side, the nearest voxel
// that is, ring by ring up to 16 voxels away (a lung deflating below its scan leaves a gap of
// several voxels that the body field, blurred over 12 mm, does not fill). Without it, a growing lung loses part of that
// rim (a quarter voxel times its area: 2.3 % of the phantom at 3 mm) and the chest wall takes lung labels where it
// slides past the pleura; with it, the warped lung's voxels are those of the deformed mesh, and labels inside the mesh
// (lobes, holes) are kept as they are.
//
// With `lung_labels` as well (the label values that are lung), a voxel outside every deformed lung
// that is carried across the pleura takes the nearest voxel outside every rest mesh that is not
// lung (the body's own tissue), where there is one within 16 voxels: the lobe map's lung rim
// outside the rest mesh is then not copied into the gap a deflating lung leaves, which made the
// warped lung 0.6-1.7 % larger than the deformed lungs below a breath-hold scan.
image::LabelMap warp_labels(const image::LabelMap& labels, const DisplacementField& pullback,
                            const std::vector<std::uint8_t>* rest_lung = nullptr,
                            std::span<const int> lung_labels = {});
// The same into `out` (its storage reused).
void warp_labels(const image::LabelMap& labels, const DisplacementField& pullback, image::LabelMap& out,
                 const std::vector<std::uint8_t>* rest_lung = nullptr, std::span<const int> lung_labels = {});

// Trilinear interpolation of the voxel values at x + v(x); `outside` where that point is more
// than half a voxel outside the image (between the outer voxel centres and the image's edge the
// edge value is kept). With `rest_lung` (per voxel of `image`: 0, or 1 + the lung whose rest mesh
// holds it, as forward_dvf's `lung` at scale 0 on the image's grid), only the corners on x's side
// of the pleura (pullback.lung[x]) are interpolated, where there is one (else the nearest voxel on
// that side, as warp_labels): no chest wall is blended into a lung voxel, and no lung into the
// chest wall.
//
// With `tissue` as well (lung_tissue: 1 where the label map calls a voxel lung, per voxel of
// `image` and per voxel of the DVF's grid, the latter from the warped label map), the corners
// must also show x's tissue: a lung voxel is interpolated from lung voxels only, and tissue the
// lung's mesh holds but the label map does not call lung (the tissue under a dome the smoothed
// surface reaches below, a vessel's hole) from that tissue only; where none of the corners with a
// weight of at least 1e-4 does, the corners on x's side as without it (so that a zero field gives
// the image back where the warped label map and the image's own disagree at the pleura). Soft
// tissue's HU + 1000 is 7 times the parenchyma's: blended into the lung voxels beside it, it
// added 0.7-1.6 % to the lungs' mass at end-inspiration (docs/voxels.md, "The lungs' mass").
struct Tissue {
  const std::vector<std::uint8_t>* rest = nullptr;    // per voxel of the image
  const std::vector<std::uint8_t>* warped = nullptr;  // per voxel of the pull-back DVF's grid
};
Image warp_image(const Image& image, const DisplacementField& pullback, float outside = kOutsideHu,
                 const std::vector<std::uint8_t>* rest_lung = nullptr, const Tissue& tissue = {});
// The same into `out` (its storage reused).
void warp_image(const Image& image, const DisplacementField& pullback, Image& out, float outside = kOutsideHu,
                const std::vector<std::uint8_t>* rest_lung = nullptr, const Tissue& tissue = {});

// warp_labels(labels, pullback, out_labels, rest_lung, lung_labels) and warp_image(image, pullback,
// out_image, outside, image_rest_lung, Tissue{image_rest_tissue, lung_tissue of out_labels}) in one
// pass over the field, for an image on the label map's own grid (a CT and its label map at a time
// point on their grid, #50: the two warps sampled the same points in two passes, and the warped
// label map's tissue in a third). The same values as those calls, bit for bit; without
// `image_rest_tissue` the image by the pleura's side alone. Throws
// ValueError for an image on another grid, or masks of other sizes.
void warp_labels_and_image(const image::LabelMap& labels, const Image& image, const DisplacementField& pullback,
                           image::LabelMap& out_labels, Image& out_image, const std::vector<std::uint8_t>* rest_lung,
                           std::span<const int> lung_labels, float outside,
                           const std::vector<std::uint8_t>* image_rest_lung,
                           const std::vector<std::uint8_t>* image_rest_tissue);

// Per voxel of `grid`: 1 where the nearest voxel of `labels` (index coordinates rounded half up,
// as warp_labels) holds one of `lung_labels`, else 0 (also outside the label map). Parallel over
// k: the same bytes at any thread count. Into `out`, its storage reused.
void lung_tissue(const image::LabelMap& labels, std::span<const int> lung_labels, const Grid& grid,
                 std::vector<std::uint8_t>& out);
// The same on the label map's own grid (a warped label map on its DVF's grid); parallel too.
void lung_tissue(const image::LabelMap& labels, std::span<const int> lung_labels, std::vector<std::uint8_t>& out);

}  // namespace pneuma::voxels
