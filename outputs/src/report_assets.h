#pragma once
// The files report.html is made of, embedded in the binary at build time (report_assets.cpp).
#include <string_view>

namespace pneuma::outputs::detail {

struct ReportAssets {
  std::string_view page;            // outputs/assets/report.html (the template)
  std::string_view script;          // outputs/assets/report.js
  std::string_view three;           // three.min.js (libjs-three)
  std::string_view gltf_loader;     // examples/js/loaders/GLTFLoader.js
  std::string_view orbit_controls;  // examples/js/controls/OrbitControls.js
};

const ReportAssets& report_assets();

}  // namespace pneuma::outputs::detail
