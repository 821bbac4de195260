// Meshes and fields: pneuma.Mesh, load_mesh, phantom, Field (compute, load, save, frames).
#include <fmt/format.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <memory>
#include <optional>

#include "bindings.h"
#include "pneuma/core/error.h"
#include "pneuma/core/parameters.h"
#include "pneuma/core/units.h"
#include "pneuma/field/tissue.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/model/field_cache.h"
#include "pneuma/model/frame.h"
#include "pneuma/scenario/physiology_config.h"
#include "pneuma/scenario/tissue_config.h"

namespace pneuma::python {
namespace {

constexpr double kMlPerM3 = units::ml_per_m3;

// ValueError "<argument>: <the table's words>", as the CLI and a scenario say it.
mesh::TriangleMesh make_mesh(const py::handle& vertices, const py::handle& triangles) {
  mesh::TriangleMesh m;
  m.vertices = array_to_points(vertices, "vertices");
  m.triangles = array_to_triangles(triangles, m.vertices.size());
  return m;
}

// A field with its model: the file's content (rest, u, force, moduli, metadata) and the
// immutable model::Model the run loop uses (normals, volume cubic, area).
struct Field {
  model::FieldRecord data;
  std::shared_ptr<const model::Model> model;

  Field(model::FieldRecord field, const mesh::BodyAxes& axes) : data(std::move(field)) {
    model = std::make_shared<const model::Model>(
        model::make_model(data.rest, data.unit_displacement, data.metadata.area_unit_m2, axes));
  }

  py::array_t<double> frame_at(double scale) const {
    model::Frame frame(*model);
    {
      py::gil_scoped_release release;
      model::advance(*model, {0, 0.0, 0.0, {scale}}, frame);
    }
    return points_to_array(frame.lungs[0].positions);
  }
  double scale_for(double volume_mL) const {
    const double target = model->lungs[0].volume_map.volume(0.0) + volume_mL / kMlPerM3;
    return model->lungs[0].volume_map.scale_for(target);
  }
};

Field compute(const mesh::TriangleMesh& rest, const std::string& tissue_name, const std::string& solver,
              double tolerance, int clique_hops, double area_unit_m2) {
  field::FieldOptions options;
  options.solver = field::parse_solver_kind(solver);
  check_argument("tolerance", parameters::kFieldTolerance, tolerance);
  check_argument("clique_hops", parameters::kCliqueHops, clique_hops);
  check_argument("area_unit_m2", parameters::kAreaUnit, area_unit_m2);
  // In range, only cg refuses a clique (of more than one hop).
  if (!field::solver_takes_clique(options.solver, clique_hops))
    throw ValueError(fmt::format("clique_hops: the {} solver takes 1 only, got {}", solver, clique_hops));
  options.tolerance = tolerance;
  options.clique_hops = clique_hops;
  options.area_unit = area_unit_m2;
  const field::Tissue tissue =
      scenario::load_tissue(scenario::tissue_file(tissue_name, scenario::default_config_dir()));
  py::gil_scoped_release release;
  const field::TissueFieldInputs inputs = field::tissue_field_inputs(rest, tissue, options);
  return Field(model::field_record(rest, inputs, field::compute_field(rest, inputs)), field::body_axes(tissue));
}

py::dict metadata_dict(const model::FieldMetadata& d) {
  py::dict out;
  out["key"] = d.key;
  out["pneuma_version"] = d.pneuma_version;
  out["tissue"] = d.tissue;
  out["solver"] = d.solver;
  out["tolerance"] = d.tolerance;
  out["clique_hops"] = d.clique_hops;
  out["path_rule"] = d.path_rule;
  out["area_unit_m2"] = d.area_unit_m2;
  out["shots"] = d.shots;
  out["iterations"] = d.iterations;
  out["residual"] = d.residual;
  return out;
}

std::optional<mesh::Lung> parse_side(const std::string& side) {
  if (side == "right") return mesh::Lung::right;
  if (side == "left") return mesh::Lung::left;
  if (side == "both") return mesh::kBothLungs;
  throw ValueError("side: expected right, left or both, got '" + side + "'");
}

}  // namespace

void register_geometry(py::module_& m) {
  py::class_<mesh::TriangleMesh>(m, "Mesh",
                                 "A triangle surface in metres: vertices (V, 3) float64 and triangles (F, 3) uint32, "
                                 "counter-clockwise seen from outside.")
      .def(py::init(&make_mesh), py::arg("vertices"), py::arg("triangles"),
           "Mesh(vertices, triangles): vertices (V, 3) in metres, triangles (F, 3) integer indices. Raises "
           "pneuma.ValueError for a wrong shape or an index out of range.")
      .def_property_readonly(
          "vertices", [](const mesh::TriangleMesh& s) { return points_to_array(s.vertices); },
          "(V, 3) float64, metres (a copy).")
      .def_property_readonly(
          "triangles", [](const mesh::TriangleMesh& s) { return triangles_to_array(s.triangles); },
          "(F, 3) uint32 vertex indices (a copy).")
      .def_property_readonly("vertex_count", &mesh::TriangleMesh::vertex_count, "Number of vertices V.")
      .def_property_readonly("triangle_count", &mesh::TriangleMesh::triangle_count, "Number of triangles F.")
      .def_property_readonly(
          "area_m2", [](const mesh::TriangleMesh& s) { return mesh::surface_area(s); }, "Total surface area (m^2).")
      .def_property_readonly(
          "volume_m3", [](const mesh::TriangleMesh& s) { return mesh::enclosed_volume(s); },
          "Enclosed volume (m^3; positive for a closed, outward-oriented surface).")
      .def("__repr__", [](const mesh::TriangleMesh& s) {
        return fmt::format("<pneuma.Mesh {} vertices, {} triangles>", s.vertex_count(), s.triangle_count());
      });

  m.def(
      "load_mesh",
      [](const std::filesystem::path& path, std::optional<std::string> unit) {
        mesh::ReadOptions read;
        if (unit) {
          read.metres_per_unit = mesh::parse_length_unit(*unit);
          read.unit_from_file = false;
        }
        py::gil_scoped_release release;
        return mesh::read_mesh(path, read);
      },
      py::arg("path"), py::arg("unit") = py::none(),
      "load_mesh(path, unit=None) -> Mesh\n\n"
      "Reads a surface (STL, OBJ, PLY, OFF, glTF, VTP, ...) into metres. `unit` is the file's length unit "
      "('mm', 'cm', 'm', ...); without it, the unit the file records, else millimetres. Raises pneuma.IoError "
      "when the file cannot be read and pneuma.InputError '<file>: <what is wrong>' for a bad file.");

  m.def(
      "phantom",
      [](const std::string& side, double edge_m) {
        mesh::PhantomOptions options;
        options.lung = parse_side(side);
        check_argument("edge_m", parameters::kEdge, edge_m);
        options.edge_length_m = edge_m;
        py::gil_scoped_release release;
        return mesh::make_lung_phantom(options);
      },
      py::arg("side") = "right", py::arg("edge_m") = parameters::kEdge.default_si,
      "phantom(side='right', edge_m=0.004) -> Mesh\n\n"
      "The built-in lung phantom ('right', 'left' or 'both'), LPS coordinates in metres, with mean edge length "
      "edge_m (metres).");

  py::class_<Field>(m, "Field",
                    "An elastostatic field on a rest mesh: frame(s) = rest + s * unit_displacement, where s counts "
                    "area units (area_unit_m2, 1 cm^2 by default) of surface-area increase. Frames come from the "
                    "engine's advance() and its exact volume cubic V(s).")
      .def(py::init([](const mesh::TriangleMesh& mesh, const std::string& tissue, const std::string& solver,
                       double tolerance, int clique_hops, double area_unit_m2) {
             return compute(mesh, tissue, solver, tolerance, clique_hops, area_unit_m2);
           }),
           py::arg("mesh"), py::kw_only(), py::arg("tissue") = "healthy-upright", py::arg("solver") = "cg",
           py::arg("tolerance") = parameters::kFieldTolerance.default_si,
           py::arg("clique_hops") = static_cast<int>(parameters::kCliqueHops.default_si),
           py::arg("area_unit_m2") = parameters::kAreaUnit.default_si,
           "Field(mesh, *, tissue='healthy-upright', solver='cg', tolerance=1e-6, clique_hops=1, area_unit_m2=1e-4)\n\n"
           "Computes the field of a Mesh. tissue: a preset name (configs/tissue) or a tissue YAML path; solver: "
           "shot, sweep, direct or cg (cg takes clique_hops 1 only). Raises pneuma.Error for a bad mesh, tissue "
           "or option.")
      .def(py::init([](const py::handle& vertices, const py::handle& triangles, const std::string& tissue,
                       const std::string& solver, double tolerance, int clique_hops, double area_unit_m2) {
             return compute(make_mesh(vertices, triangles), tissue, solver, tolerance, clique_hops, area_unit_m2);
           }),
           py::arg("vertices"), py::arg("triangles"), py::kw_only(), py::arg("tissue") = "healthy-upright",
           py::arg("solver") = "cg", py::arg("tolerance") = parameters::kFieldTolerance.default_si,
           py::arg("clique_hops") = static_cast<int>(parameters::kCliqueHops.default_si),
           py::arg("area_unit_m2") = parameters::kAreaUnit.default_si,
           "Field(vertices, triangles, *, ...): the same from arrays (vertices (V, 3) in metres, triangles (F, 3)).")
      .def_static(
          "load",
          [](const std::filesystem::path& path) {
            py::gil_scoped_release release;
            return Field(model::load_field(path), mesh::BodyAxes{});
          },
          py::arg("path"),
          "Field.load(path) -> Field\n\nReads a field file (field.h5, as `pneuma field` or `pneuma run` write it). "
          "Raises pneuma.IoError when it cannot be read, pneuma.InputError '<file>: not a pneuma field file: <why>'.")
      .def(
          "save",
          [](const Field& f, const std::filesystem::path& path) {
            py::gil_scoped_release release;
            model::save_field(path, f.data);
          },
          py::arg("path"), "save(path): writes the field file (HDF5, docs/formats.md) atomically.")
      .def_property_readonly(
          "mesh", [](const Field& f) { return f.data.rest; }, "The rest Mesh (a copy).")
      .def_property_readonly(
          "vertices", [](const Field& f) { return points_to_array(f.data.rest.vertices); },
          "Rest vertices (V, 3) float64, metres.")
      .def_property_readonly(
          "triangles", [](const Field& f) { return triangles_to_array(f.data.rest.triangles); },
          "Triangles (F, 3) uint32.")
      .def_property_readonly(
          "unit_displacement", [](const Field& f) { return points_to_array(f.data.unit_displacement); },
          "u (V, 3) float64: metres per unit of scale (one area unit of area increase).")
      .def_property_readonly(
          "force", [](const Field& f) { return column(f.data.force); }, "F per vertex for a unit load (V,) float64.")
      .def_property_readonly(
          "shear_modulus_pa", [](const Field& f) { return column(f.data.shear_modulus_pa); },
          "The tissue's shear modulus per vertex (V,) float64, Pa.")
      .def_property_readonly(
          "area_unit_m2", [](const Field& f) { return f.data.metadata.area_unit_m2; }, "The area unit s counts (m^2).")
      .def_property_readonly(
          "metadata", [](const Field& f) { return metadata_dict(f.data.metadata); },
          "dict: key, pneuma_version, tissue, solver, tolerance, clique_hops, path_rule, "
          "area_unit_m2, shots, iterations, residual.")
      .def_property_readonly(
          "rest_volume_m3", [](const Field& f) { return f.model->lungs[0].volume_map.volume(0.0); },
          "Enclosed volume of the rest mesh (m^3).")
      .def_property_readonly(
          "rest_area_m2", [](const Field& f) { return f.model->lungs[0].rest_area_m2; },
          "Surface area of the rest mesh (m^2).")
      .def_property_readonly(
          "volume_coefficients", [](const Field& f) { return f.model->lungs[0].volume_map.coefficients(); },
          "(c0, c1, c2, c3): the enclosed volume V(s) = c0 + c1 s + c2 s^2 + c3 s^3 in m^3.")
      .def_property_readonly(
          "scale_range",
          [](const Field& f) {
            return std::pair(f.model->lungs[0].volume_map.min_scale(), f.model->lungs[0].volume_map.max_scale());
          },
          "(min, max): the scales around 0 on which V(s) increases (infinite where it always does).")
      .def(
          "volume_mL",
          [](const Field& f, double scale) {
            return (f.model->lungs[0].volume_map.volume(scale) - f.model->lungs[0].volume_map.volume(0.0)) * kMlPerM3;
          },
          py::arg("scale"), "volume_mL(scale) -> float: enclosed volume of rest + scale * u minus the rest volume, mL.")
      .def("scale_for", &Field::scale_for, py::arg("volume_mL"),
           "scale_for(volume_mL) -> float: the scale s whose frame encloses the rest volume plus volume_mL "
           "(mL; negative shrinks). Raises pneuma.UnsupportedError when the field cannot reach that volume.")
      .def("frame_at", &Field::frame_at, py::arg("scale"),
           "frame_at(scale) -> (V, 3) float64: rest + scale * u, metres (the engine's advance()).")
      .def(
          "frame", [](const Field& f, double volume_mL) { return f.frame_at(f.scale_for(volume_mL)); },
          py::arg("volume_mL"),
          "frame(volume_mL) -> (V, 3) float64: the frame enclosing the rest volume plus volume_mL (mL), "
          "i.e. frame_at(scale_for(volume_mL)).")
      .def("__repr__", [](const Field& f) {
        return fmt::format("<pneuma.Field {} vertices, tissue {}, solver {}>", f.data.rest.vertex_count(),
                           f.data.metadata.tissue, f.data.metadata.solver);
      });
}

}  // namespace pneuma::python
