// pneuma mesh info|repair|remesh: inspect, repair and remesh triangle surfaces.
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "commands.h"
#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/core/parameters.h"
#include "pneuma/core/units.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/mesh/repair/remesh.h"
#include "pneuma/mesh/repair/repair.h"

namespace pneuma::cli {
namespace {

struct MeshOptions {
  std::string input;
  std::string output;
  std::string unit = "mm";
  bool unit_given = false;  // --unit on the command line: it wins over a unit recorded in the file
  bool ascii = false;
  bool skip_self_intersections = false;
  double edge_m = 0.0;
  unsigned iterations = 3;
  std::size_t max_hole_edges = mesh::RepairOptions{}.max_hole_edges;
  // from-labels
  std::vector<int> labels;
  mesh::LabelSurfaceOptions from_labels;
};

std::string yes_no(bool b) { return b ? "yes" : "no"; }

void print_quality(const char* label, const mesh::MeshQuality& q) {
  fmt::print("{}edges {:.3f} / {:.3f} / {:.3f} mm (min / mean / max), angles {:.1f} to {:.1f} deg, "
             "mean smallest angle {:.1f} deg, {:.2f} % of triangles with an angle under 30 deg\n",
             label, q.min_edge_m * 1e3, q.mean_edge_m * 1e3, q.max_edge_m * 1e3, q.min_angle_deg, q.max_angle_deg,
             q.mean_min_angle_deg, 100.0 * q.fraction_below_30_deg);
}

void print_report(const std::string& name, const mesh::TriangleMesh& m, const mesh::ValidationReport& r) {
  fmt::print("{}: {} vertices, {} triangles, {} edges, {} component{}\n", name, r.vertex_count, r.triangle_count,
             r.edge_count, r.component_count, r.component_count == 1 ? "" : "s");
  const auto box = mesh::bounding_box(m.vertices);
  const Eigen::Vector3d size = box[1] - box[0];
  fmt::print(
      "bounding box: x {:.2f} to {:.2f}, y {:.2f} to {:.2f}, z {:.2f} to {:.2f} mm (size {:.2f} x {:.2f} x {:.2f} mm)\n",
      box[0].x() * 1e3, box[1].x() * 1e3, box[0].y() * 1e3, box[1].y() * 1e3, box[0].z() * 1e3, box[1].z() * 1e3,
      size.x() * 1e3, size.y() * 1e3, size.z() * 1e3);
  fmt::print("area: {:.6g} cm^2\n", r.area_m2 * 1e4);
  if (r.closed()) fmt::print("volume: {:.6g} mL\n", r.volume_m3 * units::ml_per_m3);
  else fmt::print("volume: undefined (open surface)\n");
  print_quality("", mesh::measure_quality(m));
  fmt::print("closed: {}, manifold: {}, consistently oriented: {}, genus: {}\n", yes_no(r.closed()),
             yes_no(r.manifold()), yes_no(r.orientable && r.misoriented_face_count == 0),
             r.genus ? std::to_string(*r.genus) : "undefined");
  fmt::print("boundary edges: {}, holes: {}, non-manifold edges: {}, non-manifold vertices: {}\n",
             r.boundary_edge_count, r.hole_count, r.non_manifold_edge_count, r.non_manifold_vertex_count);
  fmt::print(
      "degenerate faces: {}, duplicated faces: {}, misoriented faces: {}, inside-out components: {}, unused vertices: {}\n",
      r.degenerate_face_count, r.duplicated_face_count, r.misoriented_face_count, r.inside_out_component_count,
      r.isolated_vertex_count);
  fmt::print("self-intersections: {}\n",
             r.self_intersection_count ? std::to_string(*r.self_intersection_count) : std::string("not checked"));
  fmt::print("{}\n", r.valid() ? "valid" : "invalid");
}

mesh::TriangleMesh load(const MeshOptions& o) {
  return mesh::read_mesh(o.input,
                         {.metres_per_unit = mesh::parse_length_unit(o.unit), .unit_from_file = !o.unit_given});
}

// The record `mesh from-labels` leaves beside its output, when there is one.
void print_provenance(const std::string& mesh_file) {
  const auto path = mesh::provenance_path(mesh_file);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return;
  std::ifstream in(path);
  std::string line;
  fmt::print("provenance ({}):\n", path.string());
  while (std::getline(in, line)) fmt::print("  {}\n", line);
}

void run_info(const MeshOptions& o) {
  const mesh::TriangleMesh m = load(o);
  const mesh::ValidationReport r = mesh::validate(m, {.check_self_intersections = !o.skip_self_intersections});
  print_report(o.input, m, r);
  print_provenance(o.input);
  if (!r.valid()) throw InputError(o.input + ": " + r.summary());
}

void run_repair(const MeshOptions& o) {
  const double unit = mesh::parse_length_unit(o.unit);
  mesh::format_for_path(o.output, o.ascii);  // an unwritable format is a usage error: say so before the work
  const mesh::TriangleMesh m = mesh::read_mesh(o.input, {.metres_per_unit = unit, .unit_from_file = !o.unit_given});
  const mesh::RepairResult result = mesh::repair(m, o.input, {.max_hole_edges = o.max_hole_edges});
  mesh::write_mesh(o.output, result.mesh, {.metres_per_unit = unit, .ascii = o.ascii});
  const auto actions = result.report.actions();
  if (actions.empty()) fmt::print("{}: nothing to repair\n", o.input);
  for (const auto& a : actions) fmt::print("{}: {}\n", o.input, a);
  fmt::print("wrote {} ({} vertices, {} triangles, closed and manifold, {:.6g} mL)\n", o.output,
             result.mesh.vertex_count(), result.mesh.triangle_count(),
             mesh::enclosed_volume(result.mesh) * units::ml_per_m3);
}

void run_remesh(const MeshOptions& o) {
  const double unit = mesh::parse_length_unit(o.unit);
  check_option("--edge", parameters::kEdge, o.edge_m);
  mesh::format_for_path(o.output, o.ascii);
  const mesh::TriangleMesh m = mesh::read_mesh(o.input, {.metres_per_unit = unit, .unit_from_file = !o.unit_given});
  // What cannot finish is refused before any of it is made.
  mesh::require_lung_sized(o.input, m, "--unit");
  const double area_m2 = mesh::surface_area(m);
  if (const double vertices = mesh::vertex_count_at_edge(area_m2, o.edge_m); !(vertices <= mesh::kMaxSurfaceVertices)) {
    throw UsageError(fmt::format("pneuma: --edge: {}: a surface of {:.4g} cm2 at an edge of {:.4g} mm would have about "
                                 "{:.3g} vertices; expected at most {:.0f} (a coarser edge)",
                                 o.input, area_m2 * 1e4, o.edge_m * 1e3, vertices, mesh::kMaxSurfaceVertices));
  }
  const mesh::RemeshOptions remesh_options{.target_edge_length_m = o.edge_m, .iterations = o.iterations};
  const mesh::ValidationReport r = mesh::validate(m);
  mesh::RemeshResult result;
  double v0 = 0.0;
  if (r.valid()) {
    result = mesh::remesh_isotropic(m, remesh_options);
    v0 = mesh::enclosed_volume(m);
  } else {
    // Repairs first, then remeshing, then the verdict (remeshing may remove what repair left).
    fmt::print("{}: not a valid surface ({}); repairing before remeshing\n", o.input, r.summary());
    mesh::RepairRemeshResult rr =
        mesh::repair_and_remesh(m, o.input, {.max_hole_edges = o.max_hole_edges}, remesh_options);
    for (const auto& a : rr.repair.actions()) fmt::print("{}: {}\n", o.input, a);
    result = std::move(rr.remesh);
    v0 = mesh::enclosed_volume(m);
  }
  mesh::write_mesh(o.output, result.mesh, {.metres_per_unit = unit, .ascii = o.ascii});
  print_quality("before: ", result.before);
  print_quality("after:  ", result.after);
  const double v1 = mesh::enclosed_volume(result.mesh);
  fmt::print("triangles {} -> {}, volume {:.6g} -> {:.6g} mL ({:+.3f} %), farthest from the input surface {:.4f} mm\n",
             m.triangle_count(), result.mesh.triangle_count(), v0 * units::ml_per_m3, v1 * units::ml_per_m3,
             100.0 * (v1 - v0) / v0, result.max_deviation_m * 1e3);
  fmt::print("wrote {}\n", o.output);
}

void run_from_labels(const MeshOptions& o) {
  // ('' reads as 0: CLI11 turns an empty item into a default-made int.)
  if (o.labels.empty() || std::any_of(o.labels.begin(), o.labels.end(), [](int label) { return label < 1; }))
    throw UsageError("pneuma: --labels: expected label values of 1 or more, such as 3,4,5");
  mesh::format_for_path(o.output, o.ascii);
  const image::LabelMap map = image::read_label_map(o.input);
  try {
    mesh::check_label_surface_size(map, o.input, o.labels, o.from_labels);
  } catch (const ValueError& e) {
    throw UsageError(std::string("pneuma: ") + e.what());  // an option's value: a usage error
  }
  const mesh::LabelSurface s = mesh::surface_from_labels(map, o.input, o.labels, o.from_labels);
  mesh::write_mesh(o.output, s.mesh, {.metres_per_unit = mesh::kMetresPerMillimetre, .ascii = o.ascii});
  const auto record = mesh::provenance_path(o.output);
  write_stream_atomically(record, false, [&](std::ostream& out) { out << s.report.provenance(); });
  for (const auto& step : s.report.steps()) fmt::print("{}: {}\n", o.input, step);
  fmt::print("wrote {} ({} vertices, {} triangles, LPS millimetres) and {}\n", o.output, s.mesh.vertex_count(),
             s.mesh.triangle_count(), record.string());
}

void add_unit_option(CLI::App& cmd, MeshOptions& o) {
  cmd.add_option("--unit", o.unit,
                 "Length of one file unit (mm, cm, m, ...), for reading (default: the unit the file "
                 "records, as pneuma's files do, else mm) and writing")
      ->capture_default_str();
}

}  // namespace

void register_mesh(CLI::App& app) {
  auto o = std::make_shared<MeshOptions>();
  CLI::App* mesh_cmd = app.add_subcommand(
      "mesh",
      "Inspect, repair and remesh triangle surfaces (STL, OBJ, PLY, OFF, glTF, VTK, ...); surfaces from label maps");
  mesh_cmd->require_subcommand(1);
  add_examples(*mesh_cmd, {"pneuma mesh info patient.stl", "pneuma mesh repair patient.stl -o repaired.ply",
                           "pneuma mesh remesh patient.vtk --edge 3mm -o remeshed.ply",
                           "pneuma mesh from-labels lobes.nii.gz --labels 3,4,5 -o right.stl"});

  CLI::App* info = mesh_cmd->add_subcommand("info", "Counts, bounding box, area, volume and the validation report; "
                                                    "exit 3 when the surface is not valid");
  info->add_option("file", o->input, "Mesh file")->required();
  add_unit_option(*info, *o);
  info->add_flag("--no-self-intersections", o->skip_self_intersections,
                 "Skip the self-intersection test (the slowest)");
  add_examples(*info, {"pneuma mesh info patient.stl", "pneuma mesh info scan.obj --unit cm --no-self-intersections"});
  info->callback([o, info] {
    o->unit_given = info->count("--unit") > 0;
    run_info(*o);
  });

  CLI::App* repair = mesh_cmd->add_subcommand("repair", "Repair what can be repaired safely, refuse the rest");
  repair->add_option("input", o->input, "Mesh file")->required();
  repair->add_option("-o,--output", o->output, "Repaired mesh (.ply, .obj or .stl)")->required();
  add_unit_option(*repair, *o);
  repair->add_option("--max-hole", o->max_hole_edges, "Fill holes of at most this many boundary edges")
      ->capture_default_str();
  repair->add_flag("--ascii", o->ascii, "ASCII PLY or STL instead of binary");
  add_examples(*repair, {"pneuma mesh repair patient.stl -o repaired.ply",
                         "pneuma mesh repair segmentation.vtp -o repaired.stl --max-hole 200 --ascii"});
  repair->callback([o, repair] {
    o->unit_given = repair->count("--unit") > 0;
    run_repair(*o);
  });

  CLI::App* remesh = mesh_cmd->add_subcommand("remesh", "Isotropic remeshing to a target edge length");
  remesh->add_option("input", o->input, "Mesh file (repaired first when it is not a valid surface)")->required();
  add_quantity_option(*remesh, "--edge", o->edge_m, parameters::kEdge.help_text(false), "length")->required();
  remesh->add_option("-o,--output", o->output, "Remeshed surface (.ply, .obj or .stl)")->required();
  remesh->add_option("--iterations", o->iterations, "Remeshing iterations")
      ->capture_default_str()
      ->check(CLI::Range(1u, 100u));
  add_unit_option(*remesh, *o);
  remesh
      ->add_option("--max-hole", o->max_hole_edges,
                   "When the input needs repair: fill holes of at most this many "
                   "boundary edges")
      ->capture_default_str();
  remesh->add_flag("--ascii", o->ascii, "ASCII PLY or STL instead of binary");
  add_examples(*remesh, {"pneuma mesh remesh patient.stl --edge 3mm -o remeshed.ply",
                         "pneuma mesh remesh repaired.ply --edge 1.5mm --iterations 5 -o fine.ply"});
  remesh->callback([o, remesh] {
    o->unit_given = remesh->count("--unit") > 0;
    run_remesh(*o);
  });

  CLI::App* labels = mesh_cmd->add_subcommand(
      "from-labels", "Surface of the union of some labels of a NIfTI label map (.nii, .nii.gz), in LPS millimetres");
  labels->add_option("labels_file", o->input, "NIfTI label map")->required();
  labels->add_option("--labels", o->labels, "Label values to join, e.g. 3,4,5 (a right lung of a lobe map)")
      ->delimiter(',')
      ->required();
  o->from_labels.edge_length_m = 2e-3;
  add_quantity_option(*labels, "--edge", o->from_labels.edge_length_m,
                      "Target facet size, " + parameters::kEdge.range() + " (default 2 mm)", "length");
  add_quantity_option(*labels, "--smooth", o->from_labels.smoothing_m,
                      "Gaussian smoothing of the mask, sigma (default 1 mm; 0 mm: none)", "length");
  add_quantity_option(*labels, "--closing", o->from_labels.closing_radius_m,
                      "Morphological closing radius: gaps between lobes, narrow tunnels (default 1.5 mm; grows up to "
                      "6 mm while the surface has handles)",
                      "length");
  labels
      ->add_option("-o,--output", o->output,
                   "Surface (.ply, .obj or .stl, millimetres); a provenance record is "
                   "written beside it (<output>.provenance.txt)")
      ->required();
  labels->add_flag("--ascii", o->ascii, "ASCII PLY or STL instead of binary");
  add_examples(*labels, {"pneuma mesh from-labels lobes.nii.gz --labels 3,4,5 -o right.stl",
                         "pneuma mesh from-labels lobes.nii.gz --labels 1,2 --edge 1mm --smooth 0.5mm -o left.ply"});
  labels->callback([o] {
    // The facet size is the surface's edge length: the same rule as every other edge.
    check_option("--edge", parameters::kEdge, o->from_labels.edge_length_m);
    if (o->from_labels.smoothing_m < 0.0) throw UsageError("pneuma: --smooth: must be a length >= 0 such as '1 mm'");
    if (o->from_labels.closing_radius_m < 0.0)
      throw UsageError("pneuma: --closing: must be a length >= 0 such as '1.5 mm'");
    o->from_labels.max_closing_radius_m =
        std::max(o->from_labels.max_closing_radius_m, o->from_labels.closing_radius_m);
    run_from_labels(*o);
  });
}

}  // namespace pneuma::cli
