// pneuma field MESH --tissue T.yaml [--solver shot|sweep|direct|cg] [--clique M] [--tol X] -o field.h5:
// precomputes the elastostatic field of a mesh and writes it, with the rest mesh, to HDF5.
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <optional>

#include "commands.h"
#include "pneuma/core/error.h"
#include "pneuma/core/parameters.h"
#include "pneuma/core/paths.h"
#include "pneuma/core/units.h"
#include "pneuma/field/field_graph.h"
#include "pneuma/field/tissue.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/model/field_cache.h"
#include "pneuma/scenario/physiology_config.h"
#include "pneuma/scenario/tissue_config.h"

namespace pneuma::cli {
namespace {

static_assert(parameters::kCliqueHops.max == field::kMaxCliqueHops, "the table's clique sizes are the field's");

struct FieldCliOptions {
  std::string mesh;
  std::string tissue;
  std::string solver;  // empty: cg for a 1-hop clique, shot otherwise
  int clique = static_cast<int>(parameters::kCliqueHops.default_si);
  double tolerance = parameters::kFieldTolerance.default_si;
  std::string output = "field.h5";
  std::string unit = "mm";
  bool unit_given = false;  // --unit given: it wins over a unit recorded in the file
  double edge_m = parameters::kEdge.default_si;
  bool quiet = false;
};

// MESH: a mesh file (read with --unit), `phantom:left|right|both` (at --edge), or the analytic
// test shape `icosphere:<radius>:<subdivisions>` (radius in metres, or with a unit: 10cm).
mesh::TriangleMesh load_mesh_for_cli(const std::string& spec, const std::string& unit, bool unit_given,
                                     double phantom_edge_m) {
  if (spec.rfind("phantom:", 0) == 0) {
    const std::string side = spec.substr(8);
    mesh::PhantomOptions phantom;
    phantom.edge_length_m = phantom_edge_m;
    if (side == "left") phantom.lung = mesh::Lung::left;
    else if (side == "right") phantom.lung = mesh::Lung::right;
    else if (side == "both") phantom.lung = mesh::kBothLungs;
    else throw UsageError("pneuma: MESH: expected phantom:left, phantom:right or phantom:both, got '" + spec + "'");
    return mesh::make_lung_phantom(phantom);
  }
  const std::string prefix = "icosphere:";
  if (spec.rfind(prefix, 0) == 0) {
    const std::string rest = spec.substr(prefix.size());
    const auto colon = rest.find(':');
    if (colon != std::string::npos) {
      const std::string radius_text = rest.substr(0, colon), level_text = rest.substr(colon + 1);
      double radius = 0.0;
      try {
        std::size_t used = 0;
        radius = std::stod(radius_text, &used);
        if (used != radius_text.size()) radius = units::parse(radius_text, units::kind::length);
      } catch (const std::exception&) {
        radius = 0.0;
      }
      int level = -1;
      try {
        std::size_t used = 0;
        level = std::stoi(level_text, &used);
        if (used != level_text.size()) level = -1;
      } catch (const std::exception&) {
        level = -1;
      }
      if (radius >= 1e-3 && radius <= 10.0 && level >= 0 && level <= 9) return mesh::make_icosphere(radius, level);
    }
    throw UsageError(
        "pneuma: MESH: expected icosphere:<radius 1 mm to 10 m>:<subdivisions 0-9>, such as icosphere:0.1:5, got '" +
        spec + "'");
  }
  mesh::ReadOptions read;
  read.metres_per_unit = mesh::parse_length_unit(unit);
  read.unit_from_file = !unit_given;
  return mesh::read_mesh(spec, read);
}

field::Tissue load_tissue_for_cli(const std::string& name_or_path) {
  const std::filesystem::path config_dir = scenario::default_config_dir();
  const std::filesystem::path file = scenario::tissue_file(name_or_path, config_dir);
  if (file.string() != name_or_path && !path_exists(file)) {
    throw UsageError("pneuma: --tissue: no preset '" + name_or_path + "' (looked for " + file.string() +
                     "; shipped presets: " + join_names(file_stems(config_dir / "tissue", ".yaml")) + ")");
  }
  return scenario::load_tissue(file);
}

void run_field(const FieldCliOptions& o) {
  field::FieldOptions options;
  check_option("--clique", parameters::kCliqueHops, o.clique);
  check_option("--tol", parameters::kFieldTolerance, o.tolerance);
  check_option("--edge", parameters::kEdge, o.edge_m);
  options.clique_hops = o.clique;
  options.tolerance = o.tolerance;
  if (!o.solver.empty()) {
    try {
      options.solver = field::parse_solver_kind(o.solver);
    } catch (const ValueError&) {
      throw UsageError("pneuma: --solver: expected one of shot, sweep, direct, cg; got '" + o.solver + "'");
    }
  }
  if (!field::solver_takes_clique(options.solver, o.clique)) {
    throw UsageError(o.solver.empty()
                         ? fmt::format("pneuma: --clique {}: the default solver (cg) takes clique 1 only; add --solver "
                                       "shot, sweep or direct",
                                       o.clique)
                         : "pneuma: --solver cg: needs --clique 1; use shot, sweep or direct for larger cliques");
  }
  const field::Tissue tissue = load_tissue_for_cli(o.tissue);
  const mesh::TriangleMesh rest = load_mesh_for_cli(o.mesh, o.unit, o.unit_given, o.edge_m);

  const field::TissueFieldInputs inputs = field::tissue_field_inputs(rest, tissue, options);
  const field::ElastostaticField field = field::compute_field(rest, inputs);
  const model::FieldRecord record = model::field_record(rest, inputs, field);
  model::save_field(o.output, record);
  if (o.quiet) return;

  double lo = std::numeric_limits<double>::infinity(), hi = 0.0, sum = 0.0;
  for (const auto& u : record.unit_displacement) {
    const double n = u.norm();
    lo = std::min(lo, n);
    hi = std::max(hi, n);
    sum += n;
  }
  const double mean = sum / static_cast<double>(std::max<std::size_t>(1, record.unit_displacement.size()));
  const auto& r = field.report;
  fmt::print("field: {} mass nodes + {} spring nodes, tissue {}, solver {} (tolerance {:g}, clique {})\n",
             field.mass_nodes, field.spring_nodes, tissue.name, r.method, options.tolerance, options.clique_hops);
  fmt::print("solve: {} shots, {} iterations, residual {:.2e}, graph {:.3f} s, solve {:.3f} s\n", r.shots, r.iterations,
             r.residual, field.graph_seconds, r.seconds);
  fmt::print("displacement per cm^2 of surface area: min {:.4g} mm, mean {:.4g} mm, max {:.4g} mm\n", lo * 1e3,
             mean * 1e3, hi * 1e3);
  fmt::print("wrote {} (key {})\n", o.output, record.metadata.key);
}

}  // namespace

void register_field(CLI::App& app) {
  auto options = std::make_shared<FieldCliOptions>();
  CLI::App* cmd = app.add_subcommand("field", "Precompute the elastostatic field of a mesh and write it to HDF5");
  cmd->add_option("mesh", options->mesh, "Mesh file, phantom:left|right|both, or icosphere:<radius>:<subdivisions>")
      ->required();
  cmd->add_option("--tissue", options->tissue,
                  "Tissue YAML file or the name of a preset in configs/tissue/ (such as healthy-upright)")
      ->required();
  cmd->add_option("--solver", options->solver,
                  "shot (the paper's), sweep, direct or cg (default: cg, which takes --clique 1 only)");
  cmd->add_option("--clique", options->clique, parameters::kCliqueHops.help_text(false))->capture_default_str();
  cmd->add_option("--tol", options->tolerance, parameters::kFieldTolerance.help_text(false))->capture_default_str();
  cmd->add_option("-o,--output", options->output, "Field file to write (HDF5)")->capture_default_str();
  cmd->add_option("--unit", options->unit,
                  "Length of one unit of the mesh file (mm, cm, m, ...; default: the unit "
                  "the file records, else mm)")
      ->capture_default_str();
  add_quantity_option(*cmd, "--edge", options->edge_m,
                      "Phantom edge length, " + parameters::kEdge.range() + " (default " +
                          parameters::kEdge.show(parameters::kEdge.default_si) + ")",
                      "length");
  cmd->add_flag("-q,--quiet", options->quiet, "Print nothing on success");
  add_examples(*cmd, {"pneuma field phantom:right --tissue healthy-upright -o field.h5",
                      "pneuma field right.ply --tissue configs/tissue/healthy-supine.yaml -o right-field.h5",
                      "pneuma field icosphere:10cm:3 --tissue healthy-upright --solver shot --clique 2 -o sphere.h5"});
  cmd->callback([options, cmd] {
    options->unit_given = cmd->count("--unit") > 0;
    run_field(*options);
  });
}

}  // namespace pneuma::cli
