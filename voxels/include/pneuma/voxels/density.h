#pragma once
// What the lungs' motion does to the tissue on voxel grids: the Jacobian image of the forward map
// (the CT-ventilation image of 4D-CT studies) and a CT whose lung parenchyma keeps its mass as the
// lungs breathe. A CT's HU + 1000 is proportional to density (air -1000 HU, water 0 HU), so
// tissue of rest density rho that the forward map stretches by J has density rho / J: an inhaling
// lung darkens (-849.5 HU at rest, about -864 HU at J = 1.1).
#include <cstdint>
#include <span>
#include <vector>

#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/lung_motion.h"
#include "pneuma/voxels/warp.h"

namespace pneuma::voxels {

// The parenchyma the mass-preserving rule applies to lies between air and water; denser voxels
// (vessels, nodules, bone) keep their HU, and no result leaves this range.
inline constexpr float kAirHu = -1000.0f;
inline constexpr float kWaterHu = 0.0f;

// The forward map's Jacobian det(I + grad u) at every voxel centre of `forward`'s grid: in a
// lung's rest tet the Jacobian of that lung's recovered gradient at the voxel's rest point
// (recovered_gradients, recovered_jacobian: continuous across the tets, without the steps of the
// per-tet exact value, tet_jacobians), elsewhere from central differences of `forward`'s
// displacement over the neighbours outside the lungs (one-sided beside a lung or the grid's edge;
// no derivative along an axis with no such neighbour). `lungs` are those `forward` was made from,
// at the same scales. Deterministic at any thread count.
void jacobian_image(std::span<const LungMotion> lungs, const DisplacementField& forward, Image& out);

// forward_dvf and jacobian_image in one rasterisation of the rest tets (a time point's voxel
// outputs rasterised them twice, #50): `field` as forward_dvf makes it, `jacobian` with the lungs'
// voxels as jacobian_image gives them; jacobian_image_outside(field, jacobian) then gives the others
// (central differences: after the field is whole). The same values, bit for bit, as the two apart.
// With `rest`, replayed from it or kept there (forward_dvf's RestRaster).
void forward_dvf_with_jacobian(const Grid& grid, std::span<const LungMotion> lungs, DisplacementField& field,
                               const OutsideField& outside, Image& jacobian, RestRaster* rest = nullptr);

// What a time point makes from the rest tets besides its forward field, each made when its
// pointer is given: the Jacobian image's lung voxels (as forward_dvf_with_jacobian), and the
// mass-preserving CT of a `ct` on the field's own grid (as mass_preserving_ct, whose `rest_lung`
// is then the field's `lung`: the same tets by the same rule on the same grid). A time point at
// the CT's own grid rasterised the rest tets once for the field and again for the CT (#50).
struct RestImages {
  Image* jacobian = nullptr;
  const Image* ct = nullptr;            // on the field's grid (Grid's size and transform, exactly)
  Image* mass_preserving_ct = nullptr;  // with `ct`
};
// forward_dvf with `images` made in the same rasterisation, bit for bit what the separate calls
// give. Throws ValueError for a `ct` not on `grid`.
void forward_dvf_with_rest_images(const Grid& grid, std::span<const LungMotion> lungs, DisplacementField& field,
                                  const OutsideField& outside, const RestImages& images, RestRaster* rest = nullptr);
void jacobian_image_outside(const DisplacementField& forward, Image& out);

// `rest_ct` with its lung parenchyma made to keep its mass at the lungs' scales: a voxel whose
// centre lies in a lung's rest tet of Jacobian J and whose value lies between air and water
// becomes (HU + 1000) / J - 1000, clamped to [air, water]; every other voxel keeps its value.
// `rest_lung` gets, per voxel of the CT, 0 or 1 + the lung whose rest tets hold it. Pulled back by
// the pull-back DVF of the same scales with that mask (warp_image), the lungs hold the rest
// scan's mass. Throws ValueError as check_lung_motion().
void mass_preserving_ct(const Image& rest_ct, std::span<const LungMotion> lungs, Image& out,
                        std::vector<std::uint8_t>& rest_lung);

// (HU + 1000) / J - 1000 within [air, water] for parenchyma (rest HU in [air, water]); else `hu`.
float mass_preserving_hu(float hu, double jacobian);

}  // namespace pneuma::voxels
