// pneuma.Animation: a scenario's frames in memory, through the same stages as `pneuma run`
// (runner::prepare), and its voxel outputs.
#include <fmt/format.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <filesystem>
#include <optional>
#include <type_traits>

#include "bindings.h"
#include "pneuma/core/error.h"
#include "pneuma/core/units.h"
#include "pneuma/model/frame.h"
#include "pneuma/outputs/tracking.h"
#include "pneuma/outputs/voxels_output.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/runner.h"
#include "scenario_handle.h"

namespace pneuma::python {
namespace {

constexpr double kMl = units::ml_per_m3;

// A scenario's frames in memory: its model (mesh, field, volume map) and the scale of every
// frame, as `pneuma run` computes them, without writing outputs. Two lungs: every per-surface
// value is a dict by side ('right', 'left'); one lung: the value itself, as always.
struct Animation {
  scenario::Scenario scenario;
  std::shared_ptr<const model::Model> model;
  std::vector<double> time_s, lung_volume_m3;
  std::vector<std::vector<double>> scales;  // [lung][frame]
  bool field_reused = false;
  // The voxel outputs' setting (outputs.voxels), made at the first voxels() call.
  std::shared_ptr<const outputs::VoxelsSpec> voxels_spec;
  mutable std::shared_ptr<const outputs::VoxelScene> voxel_scene;

  std::size_t frame_count() const { return time_s.size(); }

  // f(lung index) for the one lung, or {side: f(i)} for two.
  template <class F>
  py::object by_lung(F f) const {
    if (!model->two_lungs()) {
      auto value = f(std::size_t{0});
      if constexpr (std::is_base_of_v<py::handle, decltype(value)>) {
        return py::object(std::move(value));
      } else {
        return py::cast(value);
      }
    }
    py::dict out;
    for (std::size_t i = 0; i < model->lungs.size(); ++i) out[scenario::lung_name(model->lungs[i].side)] = f(i);
    return out;
  }

  py::object frame(std::size_t index) const {
    if (index >= frame_count()) {
      throw ValueError(fmt::format("index: expected a frame index from 0 to {}, got {}", frame_count() - 1, index));
    }
    model::Frame frame(*model);
    {
      py::gil_scoped_release release;
      model::FrameInput input{index, time_s[index], lung_volume_m3[index], {}};
      for (std::size_t i = 0; i < scales.size(); ++i) input.scale[i] = scales[i][index];
      model::advance(*model, input, frame);
    }
    return by_lung([&](std::size_t i) { return points_to_array(frame.lungs[i].positions); });
  }
  // The voxel outputs of frame `index`, as `pneuma run` writes them (outputs.voxels).
  py::dict voxels(std::size_t index) const {
    if (!voxels_spec) {
      throw ValueError("voxels: the scenario has no `outputs: voxels` (the lungs' inside is made only for it)");
    }
    if (index >= frame_count()) {
      throw ValueError(fmt::format("index: expected a frame index from 0 to {}, got {}", frame_count() - 1, index));
    }
    voxels::TimePoint point;
    {
      py::gil_scoped_release release;
      if (!voxel_scene) voxel_scene = std::make_shared<const outputs::VoxelScene>(*model, scenario, *voxels_spec);
      std::vector<double> at;
      for (const auto& lung : scales) at.push_back(lung[index]);
      voxel_scene->compute(at, point);
    }
    const voxels::Grid& grid = voxel_scene->grid();
    const auto nx = static_cast<py::ssize_t>(grid.size[0]), ny = static_cast<py::ssize_t>(grid.size[1]),
               nz = static_cast<py::ssize_t>(grid.size[2]);
    // Indexed [i, j, k(, component)] like the NIfTI files (i fastest in memory).
    auto field = [&](const voxels::DisplacementField& f) {
      constexpr auto d = static_cast<py::ssize_t>(sizeof(double));
      py::array_t<double> out({nx, ny, nz, py::ssize_t{3}}, {3 * d, 3 * d * nx, 3 * d * nx * ny, d});
      std::copy_n(f.displacement_m.front().data(), 3 * f.displacement_m.size(), out.mutable_data());
      return out;
    };
    constexpr auto w = static_cast<py::ssize_t>(sizeof(std::int32_t));
    py::array_t<std::int32_t> labels({nx, ny, nz}, {w, w * nx, w * nx * ny});
    std::copy(point.labels->labels.begin(), point.labels->labels.end(), labels.mutable_data());
    py::dict out;
    out["forward_m"] = field(point.forward);
    out["pullback_m"] = field(point.pullback);
    out["labels"] = labels;
    // Float images indexed [i, j, k] like the labels.
    auto image = [&](const voxels::Image& im) {
      constexpr auto f = static_cast<py::ssize_t>(sizeof(float));
      py::array_t<float> out_image({nx, ny, nz}, {f, f * nx, f * nx * ny});
      std::copy(im.values.begin(), im.values.end(), out_image.mutable_data());
      return out_image;
    };
    if (point.ct) out["ct"] = image(*point.ct);
    if (point.jacobian_map) out["jacobian"] = image(*point.jacobian_map);
    py::array_t<double> affine({4, 4});
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) affine.mutable_at(r, c) = grid.ijk_to_lps(r, c);
    out["ijk_to_lps"] = affine;
    out["min_jacobian"] = point.jacobian.min;
    out["max_jacobian"] = point.jacobian.max;
    out["folded_tets"] = point.jacobian.folded_tets;
    out["lung_volume_m3"] = voxel_scene->lung_volume_m3(*point.labels);
    return out;
  }
  // Points that follow the breath (outputs/tracking.h: the rule of voxels/trajectories.csv).
  py::dict trajectories(const py::array_t<double, py::array::c_style | py::array::forcecast>& points) const {
    if (points.ndim() != 2 || points.shape(1) != 3)
      throw ValueError("points: expected an (N, 3) array of positions (LPS, metres)");
    const auto n = static_cast<std::size_t>(points.shape(0));
    std::vector<Eigen::Vector3d> rest(n);
    for (std::size_t p = 0; p < n; ++p)
      rest[p] = Eigen::Vector3d(points.at(static_cast<py::ssize_t>(p), 0), points.at(static_cast<py::ssize_t>(p), 1),
                                points.at(static_cast<py::ssize_t>(p), 2));
    std::vector<outputs::PointMotion> motions(n);
    py::array_t<double> out({static_cast<py::ssize_t>(frame_count()), static_cast<py::ssize_t>(n), py::ssize_t{3}});
    {
      py::gil_scoped_release release;
      for (std::size_t p = 0; p < n; ++p) motions[p] = outputs::locate(*model, rest[p]);
      std::vector<double> at(scales.size());
      double* data = out.mutable_data();
      for (std::size_t k = 0; k < frame_count(); ++k) {
        for (std::size_t i = 0; i < scales.size(); ++i) at[i] = scales[i][k];
        for (std::size_t p = 0; p < n; ++p) {
          const Eigen::Vector3d x = outputs::moved_point(*model, rest[p], motions[p], at);
          std::copy_n(x.data(), 3, data + 3 * (k * n + p));
        }
      }
    }
    py::list moves;
    for (const auto& m : motions) moves.append(outputs::moves_with(*model, m));
    py::dict result;
    result["positions_m"] = out;
    result["moves_with"] = moves;
    return result;
  }
  // The scenario's structures (voxels.structures) at `frames`, as voxels/structures.csv and
  // structures-summary.csv (outputs/tracking.h: StructureTracker, the CLI's own rule).
  py::dict structures(const std::vector<std::size_t>& frames, std::optional<std::vector<double>> weights) const {
    if (!voxels_spec || voxels_spec->structures.empty())
      throw ValueError("structures: the scenario has no `outputs: voxels: structures`");
    if (frames.empty()) throw ValueError("frames: expected at least one frame index");
    for (const std::size_t k : frames) {
      if (k >= frame_count())
        throw ValueError(fmt::format("frames: expected frame indices from 0 to {}, got {}", frame_count() - 1, k));
    }
    const std::vector<double> w = weights ? *weights : std::vector<double>(frames.size(), 1.0);
    if (w.size() != frames.size())
      throw ValueError(fmt::format("weights: expected one per frame ({}), got {}", frames.size(), w.size()));
    if (!voxel_scene) {
      py::gil_scoped_release release;
      voxel_scene = std::make_shared<const outputs::VoxelScene>(*model, scenario, *voxels_spec);
    }
    const voxels::Grid& grid = voxel_scene->grid();
    const auto nx = static_cast<py::ssize_t>(grid.size[0]), ny = static_cast<py::ssize_t>(grid.size[1]),
               nz = static_cast<py::ssize_t>(grid.size[2]), n = static_cast<py::ssize_t>(frames.size());
    const auto b = static_cast<py::ssize_t>(sizeof(bool));
    std::vector<outputs::StructureTracker> trackers;
    std::vector<py::array_t<bool>> masks;  // [structure]: (frames, nx, ny, nz), indexed like voxels()
    for (const outputs::StructureSpec& spec : voxels_spec->structures) {
      trackers.emplace_back(std::filesystem::path{}, std::string{}, spec);
      masks.emplace_back(std::vector<py::ssize_t>{n, nx, ny, nz},
                         std::vector<py::ssize_t>{b * nx * ny * nz, b, b * nx, b * nx * ny});
    }
    voxels::TimePoint point;
    for (std::size_t t = 0; t < frames.size(); ++t) {
      {
        py::gil_scoped_release release;
        std::vector<double> at;
        for (const auto& lung : scales) at.push_back(lung[frames[t]]);
        voxel_scene->compute(at, point);
        for (auto& tracker : trackers) tracker.add(std::to_string(frames[t]), point, w[t]);
      }
      for (std::size_t s = 0; s < trackers.size(); ++s) {
        const std::vector<std::int32_t>& mask = trackers[s].mask().labels;
        std::transform(mask.begin(), mask.end(), masks[s].mutable_data() + static_cast<std::size_t>(t) * mask.size(),
                       [](std::int32_t v) { return v != 0; });
      }
    }
    const auto vector = [](const Eigen::Vector3d& x) {
      py::array_t<double> out(3);
      std::copy_n(x.data(), 3, out.mutable_data());
      return out;
    };
    py::dict out;
    for (std::size_t s = 0; s < trackers.size(); ++s) {
      outputs::StructureTracker& tracker = trackers[s];
      tracker.finish();
      py::array_t<double> volume(n), centroid({n, py::ssize_t{3}});
      for (std::size_t t = 0; t < frames.size(); ++t) {
        const auto& row = tracker.rows()[t];
        volume.mutable_at(static_cast<py::ssize_t>(t)) = row.volume_m3;
        for (py::ssize_t a = 0; a < 3; ++a) centroid.mutable_at(static_cast<py::ssize_t>(t), a) = row.centroid_m[a];
      }
      py::dict one;
      one["masks"] = masks[s];
      one["volume_m3"] = volume;
      one["centroid_m"] = centroid;
      one["weights"] = w;
      if (const auto itv = tracker.itv()) {
        py::array_t<bool> itv_mask({nx, ny, nz}, {b, b * nx, b * nx * ny});
        std::transform(itv->labels.begin(), itv->labels.end(), itv_mask.mutable_data(),
                       [](std::int32_t v) { return v != 0; });
        one["itv"] = itv_mask;
        one["itv_volume_m3"] = tracker.itv_volume_m3();
      } else {
        one["itv"] = py::none();
        one["itv_volume_m3"] = py::none();
      }
      const std::optional<std::size_t> mid = tracker.midventilation();
      one["midventilation"] = mid ? py::cast(*mid) : py::none();
      one["midventilation_m"] = mid ? py::object(vector(tracker.rows()[*mid].centroid_m)) : py::none();
      one["mean_m"] = vector(tracker.mean_position_m());
      out[py::str(tracker.spec().name)] = one;
    }
    return out;
  }
  // The frame whose time is nearest to t (frames are 1 / frame_rate apart).
  std::size_t index_at(double t) const {
    if (!(t >= time_s.front() - 1e-9 && t <= time_s.back() + 1e-9)) {
      throw ValueError(
          fmt::format("time_s: expected a time from {:g} to {:g} s, got {:g}", time_s.front(), time_s.back(), t));
    }
    const auto it = std::lower_bound(time_s.begin(), time_s.end(), t);
    std::size_t k = static_cast<std::size_t>(it - time_s.begin());
    if (k == time_s.size() || (k > 0 && t - time_s[k - 1] <= time_s[k] - t)) --k;
    return k;
  }
};

Animation make_animation(const scenario::Scenario& given, const std::optional<std::filesystem::path>& output_dir,
                         std::optional<double> edge_m) {
  Animation a;
  a.scenario = given;
  // No output folder: the field is computed (or read from an explicit cache file), not cached in one.
  if (!output_dir && a.scenario.field.cache == scenario::FieldCache::automatic)
    a.scenario.field.cache = scenario::FieldCache::off;
  if (const outputs::VoxelsSpec* voxels = outputs::requested_voxels(a.scenario))
    a.voxels_spec = std::make_shared<const outputs::VoxelsSpec>(*voxels);
  model::CompileOptions options;
  if (output_dir) options.auto_cache_file = *output_dir / "field.h5";
  options.edge_override_m = edge_m;
  options.interior = runner::requested_needs(a.scenario).interior;
  py::gil_scoped_release release;
  // The drive and the stages of `pneuma run`, so the frames are the ones it animates.
  const physiology::SimulationResult drive = scenario::simulate_physiology(a.scenario, a.scenario.frame_rate_hz);
  runner::Prepared prepared = runner::prepare(a.scenario, drive, options);
  a.field_reused = prepared.model.report.field_reused;
  a.model = std::make_shared<const model::Model>(std::move(prepared.model));
  a.time_s = drive.series.time_s;
  a.lung_volume_m3 = drive.series.volume_m3;
  for (model::LungScales& lung : prepared.scales) a.scales.push_back(std::move(lung.scales));
  return a;
}

}  // namespace

void register_animation(py::module_& m) {
  py::class_<Animation>(m, "Animation",
                        "A scenario's frames in memory, as `pneuma run` makes them (physiology at the frame rate, "
                        "the field, the volume-to-scale map), without writing outputs.")
      .def(py::init([](const py::handle& scenario, const std::optional<std::filesystem::path>& output_dir,
                       std::optional<double> edge_m) {
             if (edge_m) check_argument("edge_m", parameters::kEdge, *edge_m);
             return make_animation(to_scenario(scenario).scenario, output_dir, edge_m);
           }),
           py::arg("scenario"), py::arg("output_dir") = py::none(), py::kw_only(), py::arg("edge_m") = py::none(),
           "Animation(scenario, output_dir=None, *, edge_m=None)\n\n"
           "scenario: a Scenario, dict or path. output_dir: where the field cache (field.h5) is looked up and "
           "written as in run(); None computes the field without caching it (unless the scenario names a cache "
           "file). edge_m overrides the mesh edge length (metres).")
      .def_property_readonly(
          "time_s", [](const Animation& a) { return column(a.time_s); }, "(N,) frame times, s.")
      .def_property_readonly(
          "volume_mL", [](const Animation& a) { return column(a.lung_volume_m3, kMl); },
          "(N,) lung volume above FRC at each frame (physiology), mL.")
      .def_property_readonly(
          "lungs",
          [](const Animation& a) {
            std::vector<std::string> names;
            for (const model::LungModel& lung : a.model->lungs) names.emplace_back(scenario::lung_name(lung.side));
            return names;
          },
          "The lungs: ['right', 'left'] for two (then every per-surface value below is a dict by side), else "
          "one name ('right', 'left' for a phantom, 'lung' for a file or label map).")
      .def_property_readonly(
          "scales", [](const Animation& a) { return a.by_lung([&](std::size_t i) { return column(a.scales[i]); }); },
          "(N,) the scale s of each frame.")
      .def_property_readonly(
          "frame_count", [](const Animation& a) { return a.frame_count(); }, "N.")
      .def_property_readonly(
          "vertices",
          [](const Animation& a) {
            return a.by_lung([&](std::size_t i) { return points_to_array(a.model->lungs[i].rest.vertices); });
          },
          "Rest vertices (V, 3), metres.")
      .def_property_readonly(
          "triangles",
          [](const Animation& a) {
            return a.by_lung([&](std::size_t i) { return triangles_to_array(a.model->lungs[i].rest.triangles); });
          },
          "Triangles (F, 3) uint32.")
      .def_property_readonly(
          "unit_displacement",
          [](const Animation& a) {
            return a.by_lung([&](std::size_t i) { return points_to_array(a.model->lungs[i].unit_displacement); });
          },
          "u (V, 3), metres per unit scale.")
      .def_property_readonly(
          "rest_volume_m3",
          [](const Animation& a) {
            return a.by_lung([&](std::size_t i) { return a.model->lungs[i].volume_map.volume(0.0); });
          },
          "Enclosed volume of the rest mesh, m^3.")
      .def_property_readonly(
          "share",
          [](const Animation& a) {
            if (!a.model->two_lungs()) return py::cast(a.scenario.mesh.share);
            return a.by_lung([&](std::size_t i) { return a.model->lungs[i].share; });
          },
          "The mesh's share of the lung volume change (mesh.share; two lungs: each lung's).")
      .def_property_readonly(
          "reference_volume_mL",
          [](const Animation& a) {
            if (!a.model->two_lungs()) return py::cast(a.model->lungs[0].reference_volume_m3 * kMl);
            return a.by_lung([&](std::size_t i) { return a.model->lungs[i].reference_volume_m3 * kMl; });
          },
          "The volume above FRC the rest mesh shows (mesh.breath, placed on the breath: end_inspiration is the "
          "breath's peak), mL. Two lungs: a dict by side.")
      .def_readonly("field_reused", &Animation::field_reused, "True when the field came from the cache.")
      .def("frame", &Animation::frame, py::arg("index"),
           "frame(index) -> (V, 3) float64: the positions of frame `index` (0 to N - 1), metres; its enclosed "
           "volume is rest_volume + share * (volume_mL[index] - reference_volume_mL). Two lungs: a dict by side.")
      .def(
          "frame_at_time", [](const Animation& a, double t) { return a.frame(a.index_at(t)); }, py::arg("time_s"),
          "frame_at_time(time_s) -> (V, 3) float64: the frame nearest to time_s (frames are 1 / frame_rate apart).")
      .def("index_at_time", &Animation::index_at, py::arg("time_s"), "The index of the frame nearest to time_s.")
      .def(
          "voxels", &Animation::voxels, py::arg("index"),
          "voxels(index) -> dict: the voxel outputs of frame `index` as `pneuma run` writes them (the scenario "
          "needs `outputs: voxels`; docs/voxels.md): 'forward_m' and 'pullback_m' (nx, ny, nz, 3) float64 "
          "displacement fields in metres, LPS (forward: where each rest point goes; pull-back: out(x) = in(x + "
          "v(x))), 'labels' (nx, ny, nz) int32 the label map warped to that frame, 'ct' (nx, ny, nz) float32 "
          "where the scenario names an image (its lung parenchyma keeping its mass unless voxels.density: "
          "unchanged), 'jacobian' (nx, ny, nz) float32 the forward map's Jacobian (unless voxels.jacobian: false), 'ijk_to_lps' (4, 4) the grid (metres), 'min_jacobian', "
          "'max_jacobian', 'folded_tets', 'lung_volume_m3' (the warped lungs' voxels).")
      .def("trajectories", &Animation::trajectories, py::arg("points"),
           "trajectories(points) -> dict: points (N, 3) at rest (LPS, metres) followed through every frame, as "
           "voxels/trajectories.csv: 'positions_m' (frames, N, 3) float64, 'moves_with' a list of N ('right "
           "surface', 'left interior', 'body', ...): a point within 0.01 mm of a rest surface moves with the "
           "surface frames, one inside a lung's tetrahedra (the scenario needs `outputs: voxels`) with its "
           "inside, any other with the body's motion (docs/formats.md, \"Points and structures\").")
      .def("structures", &Animation::structures, py::arg("frames"), py::arg("weights") = py::none(),
           "structures(frames, weights=None) -> dict: each structure of the scenario's voxels.structures "
           "(a label or a mask file) at the frames (indices), as voxels/structures.csv and "
           "structures-summary.csv: by name a dict of 'masks' (len(frames), nx, ny, nz) bool (the warped mask, "
           "indexed like voxels()), 'volume_m3' and 'centroid_m' (len(frames), 3) per frame (NaN: empty), "
           "'weights' (default 1 each; the CLI weighs phase bins by their share of the breathing time), 'itv' "
           "(nx, ny, nz) bool the union of the frames with weight > 0 and 'itv_volume_m3', 'midventilation' "
           "(the index into frames whose centroid is nearest the weighted mean), 'midventilation_m', 'mean_m'.")
      .def("__len__", [](const Animation& a) { return a.frame_count(); })
      .def("__repr__", [](const Animation& a) {
        return fmt::format("<pneuma.Animation '{}' {} frames, {} vertices{}>", a.scenario.name, a.frame_count(),
                           a.model->vertex_count(), a.model->two_lungs() ? " in two lungs" : "");
      });
}

}  // namespace pneuma::python
