#pragma once
// A run's surface source made into the surfaces the field is computed on: the built-in phantom,
// a surface file (read, repaired, remeshed) or a label map (its lungs' segment names resolved, each
// lung extracted apart from the other's labels, remeshed). The label map is read once, on first
// use, and shared: with the second lung, and with whoever asks for it (the voxel outputs).
//
// Surfaces are made lazily, lung by lung: a caller that finds a field cached under
// surface_key() never pays for the reading, repair or remeshing. surface() may be called for the
// two lungs on two threads at once.
#include <tbb/collaborative_call_once.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pneuma/image/label_map.h"
#include "pneuma/mesh/anatomy/lung.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

// One lung's part of the source.
struct LungSource {
  std::optional<Lung> phantom;           // the built-in phantom of this side
  std::filesystem::path file;            // a surface file (else the shared label map, or the phantom)
  std::vector<int> label_values;         // of the shared label map
  std::vector<std::string> label_names;  // segment names, resolved against the map (resolve())
  std::string label_key;                 // where the labels were given, for messages ("mesh.values")
};

struct SurfaceSourceSpec {
  std::vector<LungSource> lungs;      // one, or two (right then left)
  std::filesystem::path labels_file;  // the label map the lungs' labels refer to (empty: none)
  double metres_per_unit = 1e-3;      // a file's unit
  bool unit_from_file = false;        // a unit the file records wins over metres_per_unit
  bool repair = true;                 // repair what is safe before use
  double edge_m = 0.0;                // phantom resolution, remeshing target (0: keep a file's mesh)
  // Where the inputs were named, for messages: the scenario file, the key of the edge ("mesh.edge"
  // or "--edge").
  std::string origin;
  std::string edge_key = "mesh.edge";
  std::string lungs_key = "mesh.lungs";  // where two lungs' labels were given
};

class SurfaceSource {
 public:
  // Resolves segment names against the label map (read here only when names are given). Throws
  // InputError "<origin>: <label_key>: ..." for a name the map does not hold, or a label reached
  // by both lungs; IoError/InputError from reading the map.
  explicit SurfaceSource(SurfaceSourceSpec spec);

  std::size_t lung_count() const { return spec_.lungs.size(); }
  bool two_lungs() const { return spec_.lungs.size() == 2; }
  const LungSource& lung(std::size_t i) const { return spec_.lungs[i]; }
  bool is_phantom(std::size_t i) const { return spec_.lungs[i].phantom.has_value(); }
  bool from_labels() const { return !spec_.labels_file.empty(); }
  // The file lung i's surface comes from (the label map, the surface file; empty for a phantom).
  const std::filesystem::path& input_file(std::size_t i) const;

  // What shapes lung i's surface besides its input file's bytes ("labels unit ... edge ..."), for
  // the field cache's key (the phantom is keyed by its surface itself).
  std::string key_text(std::size_t i) const;

  // Lung i's surface (metres, LPS), made now: the phantom at the edge, a file read, checked,
  // repaired and remeshed, a label map's lung extracted (apart from the other lung's labels) and
  // remeshed. Throws InputError for a surface too large to make (naming origin and edge_key) or a
  // file more than a metre across, and what the readers, repair and extraction throw.
  TriangleMesh surface(std::size_t i) const;
  // The file's own surface, read and (where asked) repaired, not remeshed (`export: original`).
  TriangleMesh original_surface(std::size_t i) const;

  // The label map, read on the first call and then shared (null without one).
  std::shared_ptr<const image::LabelMap> label_map() const;
  // The label map's outer faces that lung i's labels reach, each named by the side of the body it
  // faces and its slice ("inferior face (k = 0)"), in the order i, j, k and first then last; empty
  // without a label map. There the scan, not anatomy, cut the lung flat.
  std::vector<std::string> edges_touched(std::size_t i) const;

 private:
  // Two lungs' maps without the band where they touch, made for the first lung that asks and
  // reused for the other (the band is the same seen from either lung).
  std::shared_ptr<const image::LabelMap> separated_map() const;

  SurfaceSourceSpec spec_;
  // The lazily made maps; the two lungs' surfaces may be made on two threads (model/compile.cpp).
  // Made once, collaboratively (#50): a lung that asks while the other lung is reading or
  // separating the map joins that work's parallel loops instead of sleeping on a lock, so the
  // shipped scenario's first second (inflating, converting and separating 70.8 M voxels) runs on
  // every core.
  mutable tbb::collaborative_once_flag map_once_, separated_once_;
  mutable std::shared_ptr<const image::LabelMap> map_;
  mutable std::shared_ptr<const image::LabelMap> separated_;
};

}  // namespace pneuma::mesh
