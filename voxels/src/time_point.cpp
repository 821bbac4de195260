#include "pneuma/voxels/time_point.h"

#include <algorithm>
#include <cstring>
#include <functional>
#include <tuple>

#include "pneuma/core/error.h"
#include "pneuma/voxels/density.h"
#include "pneuma/voxels/voxel_io.h"

namespace pneuma::voxels {

TimePoint compute_time_point(const Grid& grid, std::span<const LungMotion> lungs, const TimePointInputs& inputs) {
  TimePoint point;
  compute_time_point(grid, lungs, inputs, point);
  return point;
}

namespace {

enum class Part { forward, pullback, labels, ct, jacobian };

// compute_time_point, calling ready(part) as each part's buffer becomes final.
template <typename Ready>
void compute_parts(const Grid& grid, std::span<const LungMotion> lungs, const TimePointInputs& inputs, TimePoint& point,
                   const Ready& ready) {
  // A CT on the time point's own grid: its mass-preserving rest CT made in the forward field's
  // rasterisation of the rest tets, and the rest lungs on its grid those of the forward field.
  const bool ct_on_grid = inputs.ct != nullptr && inputs.ct->grid.size == grid.size &&
                          inputs.ct->grid.ijk_to_lps == grid.ijk_to_lps &&
                          inputs.ct->values.size() == grid.voxel_count();
  // The rest tets kept for a later time point only when one will replay them (0.33 GB at
  // case004's own grid); replayed when an earlier one kept them.
  RestRaster* const raster =
      inputs.keep_rest_raster || point.rest_raster.holds(grid, lungs) ? &point.rest_raster : nullptr;
  RestImages images;
  if (inputs.jacobian_map) {
    // The Jacobian image's lung voxels from the forward field's rasterisation of the rest tets.
    if (!point.jacobian_map) point.jacobian_map.emplace();
    images.jacobian = &*point.jacobian_map;
  }
  if (ct_on_grid && inputs.mass_preserving) {
    images.ct = inputs.ct;
    images.mass_preserving_ct = &point.rest_ct;
  }
  if (images.jacobian != nullptr || images.mass_preserving_ct != nullptr) {
    forward_dvf_with_rest_images(grid, lungs, point.forward, inputs.forward_outside, images, raster);
  } else {
    forward_dvf(grid, lungs, point.forward, inputs.forward_outside, raster);
  }
  // The last time point to replay the kept rest tets frees them once replayed (#50), not when the
  // run ends: 0.33 GB at case004's own grid through the pull-back and the warps.
  if (!inputs.keep_rest_raster) point.rest_raster = RestRaster{};
  ready(Part::forward);
  pullback_dvf(grid, lungs, point.pullback, inputs.pullback_outside);
  ready(Part::pullback);
  point.jacobian = jacobian_stats(lungs);
  if (inputs.labels == nullptr) point.labels.reset();
  if (inputs.ct == nullptr) point.ct.reset();
  if (inputs.labels != nullptr && !point.labels) point.labels.emplace();
  if (inputs.ct != nullptr && !point.ct) point.ct.emplace();
  // A CT on the label map's own grid: both warped in one pass (they sample the same points).
  const bool fused = inputs.labels != nullptr && inputs.ct != nullptr && inputs.ct->grid.size == inputs.labels->size &&
                     inputs.ct->grid.ijk_to_lps == inputs.labels->ijk_to_lps;
  if (inputs.labels != nullptr && !fused) {
    warp_labels(*inputs.labels, point.pullback, *point.labels, inputs.rest_lung, inputs.lung_labels);
    ready(Part::labels);
  }
  if (inputs.ct != nullptr) {
    // Pulled back with the rest lungs on the CT's grid, so that nothing is blended across the
    // sliding pleura (the mass-preserving rule finds them on its way), and with the label map's
    // lung tissue on both grids, so that no tissue is blended into the lung and the warped CT's
    // lung is the warped label map's.
    const bool by_tissue = inputs.labels != nullptr && !inputs.lung_labels.empty();
    if (by_tissue) lung_tissue(*inputs.labels, inputs.lung_labels, inputs.ct->grid, point.ct_tissue);
    if (!ct_on_grid) {
      if (inputs.mass_preserving) {
        mass_preserving_ct(*inputs.ct, lungs, point.rest_ct, point.ct_lung);
      } else {
        point.ct_lung = rest_lungs(inputs.ct->grid, lungs);
      }
    }
    const std::vector<std::uint8_t>* const ct_lung = ct_on_grid ? &point.forward.lung : &point.ct_lung;
    const Image& rest_ct = inputs.mass_preserving ? point.rest_ct : *inputs.ct;
    if (fused) {
      warp_labels_and_image(*inputs.labels, rest_ct, point.pullback, *point.labels, *point.ct, inputs.rest_lung,
                            inputs.lung_labels, kOutsideHu, ct_lung, by_tissue ? &point.ct_tissue : nullptr);
      ready(Part::labels);
    } else {
      Tissue tissue;
      if (by_tissue) {
        lung_tissue(*point.labels, inputs.lung_labels, point.warped_tissue);
        tissue = {&point.ct_tissue, &point.warped_tissue};
      }
      warp_image(rest_ct, point.pullback, *point.ct, kOutsideHu, ct_lung, tissue);
    }
    ready(Part::ct);
  }
  if (inputs.jacobian_map) {
    jacobian_image_outside(point.forward, *point.jacobian_map);
    ready(Part::jacobian);
  } else {
    point.jacobian_map.reset();
  }
}

void check_extension(const std::string& extension) {
  if (extension != ".nii.gz" && extension != ".nii" && extension != ".mha" && extension != ".nrrd") {
    throw ValueError("voxel file extension '" + extension + "': expected .nii.gz, .nii, .mha or .nrrd");
  }
}

// The file of one part, its name in `files`; the writing itself returned, to run now or later.
std::function<void()> part_file(const std::filesystem::path& folder, const std::string& tag, const TimePoint& point,
                                Part part, const std::string& extension, DvfConvention convention,
                                TimePointFiles& files) {
  switch (part) {
    case Part::forward:
      files.forward = folder / ("dvf-forward-" + tag + extension);
      return [path = files.forward, &point, convention] {
        write_dvf(path, point.forward, DvfDirection::forward, convention);
      };
    case Part::pullback:
      files.pullback = folder / ("dvf-pullback-" + tag + extension);
      return [path = files.pullback, &point, convention] {
        write_dvf(path, point.pullback, DvfDirection::pullback, convention);
      };
    case Part::labels:
      files.labels = folder / ("labels-" + tag + extension);
      return [path = files.labels, &point] { write_label_map(path, *point.labels); };
    case Part::ct:
      files.ct = folder / ("ct-" + tag + extension);
      return [path = files.ct, &point] { write_image(path, *point.ct); };
    case Part::jacobian:
      files.jacobian = folder / ("jacobian-" + tag + extension);
      return [path = files.jacobian, &point] { write_image(path, *point.jacobian_map); };
  }
  return [] {};
}

}  // namespace

void compute_time_point(const Grid& grid, std::span<const LungMotion> lungs, const TimePointInputs& inputs,
                        TimePoint& point) {
  compute_parts(grid, lungs, inputs, point, [](Part) {});
}

TimePointFiles compute_and_write_time_point(const Grid& grid, std::span<const LungMotion> lungs,
                                            const TimePointInputs& inputs, TimePoint& point,
                                            const std::filesystem::path& folder, const std::string& tag,
                                            WriteQueue& writes, const std::string& extension,
                                            DvfConvention convention) {
  check_extension(extension);
  TimePointFiles files;
  compute_parts(grid, lungs, inputs, point,
                [&](Part part) { writes.add(part_file(folder, tag, point, part, extension, convention, files)); });
  return files;
}

TimePointFiles write_time_point(const std::filesystem::path& folder, const std::string& tag, const TimePoint& point,
                                const std::string& extension, DvfConvention convention) {
  check_extension(extension);
  TimePointFiles files;
  std::vector<Part> parts{Part::forward, Part::pullback};
  if (point.labels) parts.push_back(Part::labels);
  if (point.ct) parts.push_back(Part::ct);
  if (point.jacobian_map) parts.push_back(Part::jacobian);
  for (const Part part : parts) part_file(folder, tag, point, part, extension, convention, files)();
  return files;
}

TimePointSequences::TimePointSequences(std::filesystem::path folder, std::vector<SequenceFormat> formats,
                                       std::string index_name, std::string index_unit, std::vector<double> index_values,
                                       SequenceVoxel labels, DvfConvention convention)
    : folder_(std::move(folder)), formats_(std::move(formats)), labels_(labels) {
  base_.nifti_ras = convention == DvfConvention::nifti;
  base_.index_name = std::move(index_name);
  base_.index_unit = std::move(index_unit);
  base_.index_values = std::move(index_values);
}

void TimePointSequences::append_item(const std::string& kind, const Grid& grid, SequenceVoxel voxel, const void* values,
                                     std::size_t bytes, const std::string& field_type) {
  for (const SequenceFormat format : formats_) {
    const std::string name = kind + (format == SequenceFormat::slicer_nrrd ? ".seq.nrrd" : "-4d.nii.gz");
    auto it = std::find_if(writers_.begin(), writers_.end(), [&](const auto& w) { return w.first == name; });
    if (it == writers_.end()) {
      SequenceSpec spec = base_;
      spec.grid = grid;
      spec.voxel = voxel;
      spec.label_map = kind == "labels";
      spec.displacement_field_type = field_type;
      writers_.emplace_back(name, std::make_unique<SequenceWriter>(folder_ / name, format, spec));
      it = writers_.end() - 1;
    }
    it->second->append(values, bytes);
  }
}

void TimePointSequences::append(const TimePoint& point) {
  if (point.labels) {
    const std::vector<std::int32_t>& labels = point.labels->labels;
    const std::size_t size = labels_ == SequenceVoxel::uint8 ? 1 : labels_ == SequenceVoxel::int16 ? 2 : 4;
    label_scratch_.resize(labels.size() * size);
    for (std::size_t v = 0; v < labels.size(); ++v) {
      if (size == 1) {
        label_scratch_[v] = static_cast<char>(static_cast<std::uint8_t>(labels[v]));
      } else if (size == 2) {
        const auto x = static_cast<std::int16_t>(labels[v]);
        std::memcpy(label_scratch_.data() + 2 * v, &x, 2);
      } else {
        std::memcpy(label_scratch_.data() + 4 * v, &labels[v], 4);
      }
    }
    append_item("labels", grid_of(*point.labels), labels_, label_scratch_.data(), label_scratch_.size());
  }
  if (point.ct) {
    append_item("ct", point.ct->grid, SequenceVoxel::float32, point.ct->values.data(),
                point.ct->values.size() * sizeof(float));
  }
  if (point.jacobian_map) {
    append_item("jacobian", point.jacobian_map->grid, SequenceVoxel::float32, point.jacobian_map->values.data(),
                point.jacobian_map->values.size() * sizeof(float));
  }
  for (const auto& [kind, field, type] : {std::tuple{"dvf-pullback", &point.pullback, "resampling"},
                                          std::tuple{"dvf-forward", &point.forward, "modeling"}}) {
    scratch_.resize(3 * field->displacement_m.size());
    for (std::size_t v = 0; v < field->displacement_m.size(); ++v)
      for (std::size_t c = 0; c < 3; ++c)
        scratch_[3 * v + c] = static_cast<float>(field->displacement_m[v][static_cast<Eigen::Index>(c)] * 1e3);
    append_item(kind, field->grid, SequenceVoxel::vector3, scratch_.data(), scratch_.size() * sizeof(float), type);
  }
}

std::vector<std::filesystem::path> TimePointSequences::finish() {
  std::vector<std::filesystem::path> files;
  for (auto& [name, writer] : writers_) files.push_back(writer->finish());
  return files;
}

}  // namespace pneuma::voxels
