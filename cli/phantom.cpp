// pneuma phantom --lung left|right|both --edge 2mm -o lungs.ply: the built-in lung phantom.
#include <fmt/format.h>

#include <map>
#include <memory>
#include <optional>
#include <string>

#include "commands.h"
#include "pneuma/core/error.h"
#include "pneuma/core/parameters.h"
#include "pneuma/core/units.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/mesh/io/mesh_io.h"

namespace pneuma::cli {
namespace {

// --help gives the table's default: it must be the phantom's.
static_assert(parameters::kEdge.default_si == mesh::PhantomOptions{}.edge_length_m);

struct PhantomCliOptions {
  std::string lung = "both";
  double edge_m = mesh::kDefaultPhantom.edge_length_m;
  std::string output;
  std::string unit = "mm";
  bool ascii = false;
};

void run_phantom(const PhantomCliOptions& o) {
  const double unit = mesh::parse_length_unit(o.unit);
  check_option("--edge", parameters::kEdge, o.edge_m);
  mesh::format_for_path(o.output, o.ascii);
  const std::map<std::string, std::optional<mesh::Lung>> lungs{
      {"right", mesh::Lung::right}, {"left", mesh::Lung::left}, {"both", mesh::kBothLungs}};
  const auto lung = lungs.find(o.lung);
  if (lung == lungs.end()) throw UsageError("pneuma: --lung: expected left, right or both, got '" + o.lung + "'");
  const mesh::TriangleMesh m = mesh::make_lung_phantom({.lung = lung->second, .edge_length_m = o.edge_m});
  mesh::write_mesh(o.output, m, {.metres_per_unit = unit, .ascii = o.ascii});
  const auto box = mesh::bounding_box(m.vertices);
  fmt::print("wrote {}: {} vertices, {} triangles, volume {:.4g} mL, height {:.1f} mm (LPS frame, z up)\n", o.output,
             m.vertex_count(), m.triangle_count(), mesh::enclosed_volume(m) * units::ml_per_m3,
             (box[1].z() - box[0].z()) * 1e3);
}

}  // namespace

void register_phantom(CLI::App& app) {
  auto o = std::make_shared<PhantomCliOptions>();
  CLI::App* cmd = app.add_subcommand("phantom", "Write the built-in lung phantom (adult lungs at FRC)");
  cmd->add_option("--lung", o->lung, "left, right or both (two components, right lung first)")->capture_default_str();
  add_quantity_option(*cmd, "--edge", o->edge_m, parameters::kEdge.help_text(), "length");
  cmd->add_option("-o,--output", o->output, "Mesh file to write (.ply, .obj or .stl)")->required();
  cmd->add_option("--unit", o->unit, "Length of one file unit (mm, cm, m, ...)")->capture_default_str();
  cmd->add_flag("--ascii", o->ascii, "ASCII PLY or STL instead of binary");
  add_examples(*cmd, {"pneuma phantom --lung right --edge 2mm -o right.ply",
                      "pneuma phantom --lung both -o lungs.stl --unit m"});
  cmd->callback([o] { run_phantom(*o); });
}

}  // namespace pneuma::cli
