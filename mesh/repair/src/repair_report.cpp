// RepairReport's lines, apart from repair.cpp's CGAL: the phantom-only build (no repair) has them too.
#include <fmt/format.h>

#include <string>
#include <vector>

#include "pneuma/mesh/repair/repair.h"

namespace pneuma::mesh {
namespace {

std::string count_of(std::size_t n, const char* one, const char* many) {
  return fmt::format("{} {}", n, n == 1 ? one : many);
}

}  // namespace

std::vector<std::string> RepairReport::actions() const {
  std::vector<std::string> a;
  if (merged_vertices)
    a.push_back("merged " + count_of(merged_vertices, "vertex", "vertices") + " at identical positions");
  if (removed_degenerate_faces)
    a.push_back("removed " + count_of(removed_degenerate_faces, "degenerate face", "degenerate faces"));
  if (removed_duplicated_faces)
    a.push_back("removed " + count_of(removed_duplicated_faces, "duplicated face", "duplicated faces"));
  if (flipped_faces) a.push_back("flipped " + count_of(flipped_faces, "face", "faces") + " to match their neighbours");
  if (stitched_edges)
    a.push_back("stitched " + count_of(stitched_edges, "pair of border edges", "pairs of border edges"));
  if (filled_holes)
    a.push_back("filled " + count_of(filled_holes, "hole", "holes") + " with " +
                count_of(added_faces, "face", "faces"));
  if (reversed_components)
    a.push_back("reversed " + count_of(reversed_components, "inside-out component", "inside-out components"));
  if (self_intersecting_pairs) {
    a.push_back(
        fmt::format("removed {} around {} ({}), first faces {} and {}; the holes are refilled",
                    count_of(removed_intersecting_faces, "face", "faces"),
                    count_of(self_intersecting_pairs, "pair of intersecting faces", "pairs of intersecting faces"),
                    rounds == 1 ? "1 round" : fmt::format("{} rounds", rounds), first_intersecting_faces[0],
                    first_intersecting_faces[1]));
  }
  if (dropped_components) {
    a.push_back(fmt::format("dropped {} ({}, {:.4g} mm^2), each under {:g} % of the largest component's area",
                            count_of(dropped_components, "small component", "small components"),
                            count_of(dropped_component_faces, "face", "faces"), dropped_component_area_m2 * 1e6,
                            100.0 * min_component_fraction));
  }
  if (rebuilt_components) {
    a.push_back(fmt::format(
        "rebuilt {} from its inside ({}): a {:.3g} mm voxel grid, facets of {:.3g} mm, enclosed "
        "volume {:.4g} -> {:.4g} mL ({:+.2f} %)",
        count_of(rebuilt_components, "component", "components"), rebuilt_for, rebuilt_voxel_m * 1e3,
        rebuilt_edge_m * 1e3, rebuilt_volume_before_m3 * 1e6, rebuilt_volume_after_m3 * 1e6,
        rebuilt_volume_before_m3 > 0.0 ? 100.0 * (rebuilt_volume_after_m3 / rebuilt_volume_before_m3 - 1.0) : 0.0));
  }
  if (handles_removed)
    a.push_back("removed " + count_of(static_cast<std::size_t>(handles_removed), "handle", "handles"));
  if (handles_kept) {
    a.push_back("kept " + count_of(static_cast<std::size_t>(handles_kept), "handle", "handles") + " (genus " +
                std::to_string(handles_kept) + "): " + handles_kept_because);
  }
  if (remeshed_edge_m > 0.0) {
    a.push_back(fmt::format("remeshed at {:.3g} mm before the verdict, which removed what repair left: {}",
                            remeshed_edge_m * 1e3, left_for_remeshing));
  }
  if (dropped_vertices) a.push_back("dropped " + count_of(dropped_vertices, "unused vertex", "unused vertices"));
  return a;
}

}  // namespace pneuma::mesh
