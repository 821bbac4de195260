// The report's template, its script and three.js, embedded into the binary at build time with
// the assembler's .incbin (paths from CMake: outputs/CMakeLists.txt finds libjs-three at
// configure time). Why embedded and not read at run time: `pneuma run` then works wherever the
// binary is copied, with or without libjs-three installed there, and a report's bytes depend
// only on the binary and the run (docs/formats.md). The build reruns this file's compilation
// when one of the embedded files changes (OBJECT_DEPENDS); ccache does not cache .incbin
// translation units, so a stale copy is never reused.
#include "report_assets.h"

// Defines <name> and <name>_end around the bytes of `file` in .rodata, plus a NUL after them.
// NOLINTBEGIN(bugprone-macro-parentheses): `name` is an identifier (a symbol, a declarator), never an expression
#define PNEUMA_EMBED(name, file)                \
  asm(".pushsection .rodata\n"                  \
      ".balign 16\n"                            \
      ".global " #name "\n"                     \
      ".hidden " #name "\n" #name ":\n"         \
      ".incbin \"" file "\"\n"                  \
      ".global " #name "_end\n"                 \
      ".hidden " #name "_end\n" #name "_end:\n" \
      ".byte 0\n"                               \
      ".popsection\n");                         \
  extern "C" const char name[];                 \
  extern "C" const char name##_end[];
// NOLINTEND(bugprone-macro-parentheses)

PNEUMA_EMBED(pneuma_report_page, PNEUMA_REPORT_PAGE)
PNEUMA_EMBED(pneuma_report_script, PNEUMA_REPORT_SCRIPT)
PNEUMA_EMBED(pneuma_report_three, PNEUMA_THREE_JS)
PNEUMA_EMBED(pneuma_report_gltf_loader, PNEUMA_THREE_GLTF_LOADER_JS)
PNEUMA_EMBED(pneuma_report_orbit_controls, PNEUMA_THREE_ORBIT_CONTROLS_JS)

namespace pneuma::outputs::detail {
namespace {

std::string_view span(const char* begin, const char* end) { return {begin, static_cast<std::size_t>(end - begin)}; }

}  // namespace

const ReportAssets& report_assets() {
  static const ReportAssets assets{
      span(pneuma_report_page, pneuma_report_page_end),
      span(pneuma_report_script, pneuma_report_script_end),
      span(pneuma_report_three, pneuma_report_three_end),
      span(pneuma_report_gltf_loader, pneuma_report_gltf_loader_end),
      span(pneuma_report_orbit_controls, pneuma_report_orbit_controls_end),
  };
  return assets;
}

}  // namespace pneuma::outputs::detail
