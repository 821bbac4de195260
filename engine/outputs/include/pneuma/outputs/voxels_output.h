#pragma once
// Voxel outputs (#31; docs/voxels.md, formats.md "Voxel outputs"): at chosen time points, the
// forward and pull-back DVFs of the whole chest (the lungs' interior field inside them, the body
// motion below them, 0 elsewhere), the label map and the CT pulled back, and per time point the
// Jacobian of the forward map inside the lungs and the warped lungs' volume (voxels/voxels.csv).
//
//   outputs:
//     voxels:                          # off by default
//       at: [end_expiration, end_inspiration, 2.4 s]   # the frames of the lowest and highest
//                                      # volume, and the frame nearest to a time (the default: the first two)
//       spacing: 2 mm                  # a grid of this spacing over the label map's extent (default:
//                                      # the label map's own grid; lungs without one: 2 mm over their box)
//       image: ct.nii.gz               # a CT on the label map's geometry (or its own) to pull back
//       format: nii.gz                 # nii.gz | nii | mha
//
// Files (voxels/): dvf-forward-<t>, dvf-pullback-<t>, labels-<t> and ct-<t> with <t> the frame's
// time ("2.400s"), and voxels.csv. Label-map lungs warp the label map; other lungs (the phantom,
// surface files) warp a label map of their rest tetrahedra (1 right or the only lung, 2 left).
#include <filesystem>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "pneuma/outputs/output.h"

namespace pneuma::voxels {
struct Image;
}

namespace pneuma::outputs {

// A time point: the frame of the run's lowest or highest volume, or the frame nearest to a time.
enum class VoxelMoment { end_expiration, end_inspiration };
using VoxelTime = std::variant<VoxelMoment, double>;

struct VoxelsSpec {
  std::vector<VoxelTime> at{VoxelMoment::end_expiration, VoxelMoment::end_inspiration};
  double spacing_m = 0.0;  // 0: the label map's grid (2 mm where there is none)
  std::shared_ptr<const voxels::Image> image;
  std::filesystem::path image_file;
  std::string extension = ".nii.gz";
};

OutputPlugin voxels_output();

}  // namespace pneuma::outputs
