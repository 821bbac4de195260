#pragma once
// A small, dependency-free SVG line-plot writer for the paper figures: linear or logarithmic
// axes, several series, a legend. Output is deterministic (fixed number formatting), so the
// same data gives the same bytes.
#include <string>
#include <vector>
#include "pneuma/core/error.h"

namespace pneuma::paper {

struct PlotSeries {
  std::string label;
  std::vector<double> x, y;
  bool dashed = false;
  bool markers = false;  // a dot at every point (for short series)
};

struct LinePlot {
  std::string title, x_label, y_label;
  bool log_x = false, log_y = false;  // points with a coordinate <= 0 on a log axis are skipped
  std::vector<PlotSeries> series;
};

// The plot as a complete SVG document (720 x 450 px). Throws ValueError when no
// series has a drawable point.
std::string render_svg(const LinePlot& plot);

}  // namespace pneuma::paper
