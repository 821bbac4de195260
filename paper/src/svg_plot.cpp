#include "pneuma/paper/svg_plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "pneuma/core/error.h"
#include "pneuma/core/markup.h"

namespace pneuma::paper {
namespace {

constexpr double width = 720, height = 450;
constexpr double left = 80, right = 200, top = 40, bottom = 60;  // margins; the legend sits right
const char* const palette[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#17becf", "#7f7f7f"};

struct Axis {
  double low = 0, high = 1;
  bool log = false;
  double map(double v, double pixel_low, double pixel_high) const {
    const double a = log ? std::log10(low) : low, b = log ? std::log10(high) : high;
    const double t = ((log ? std::log10(v) : v) - a) / (b - a);
    return pixel_low + t * (pixel_high - pixel_low);
  }
};

bool drawable(double v, bool log) { return std::isfinite(v) && (!log || v > 0.0); }

Axis make_axis(const std::vector<double>& values, bool log) {
  Axis a;
  a.log = log;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double v : values) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  if (log) {
    a.low = std::pow(10.0, std::floor(std::log10(lo)));
    a.high = std::pow(10.0, std::ceil(std::log10(hi)));
    if (a.high <= a.low) a.high = a.low * 10.0;
  } else {
    if (hi <= lo) {
      lo -= 0.5;
      hi += 0.5;
    }
    const double pad = 0.04 * (hi - lo);
    a.low = lo - pad;
    a.high = hi + pad;
  }
  return a;
}

// Tick positions: decades on a log axis (thinned to at most 8), "nice" steps otherwise.
std::vector<double> ticks(const Axis& a) {
  std::vector<double> out;
  if (a.log) {
    const int first = static_cast<int>(std::round(std::log10(a.low)));
    const int last = static_cast<int>(std::round(std::log10(a.high)));
    const int stride = std::max(1, (last - first + 7) / 8);
    for (int e = first; e <= last; e += stride) out.push_back(std::pow(10.0, e));
    return out;
  }
  const double raw = (a.high - a.low) / 6.0;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  double step = magnitude;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * magnitude >= raw) {
      step = m * magnitude;
      break;
    }
  }
  for (double t = std::ceil(a.low / step) * step; t <= a.high + 1e-9 * step; t += step)
    out.push_back(std::abs(t) < 1e-12 * step ? 0.0 : t);
  return out;
}

std::string tick_label(double v, bool log) {
  if (log) return fmt::format("1e{}", static_cast<int>(std::round(std::log10(v))));
  return fmt::format("{:g}", v);
}

}  // namespace

std::string render_svg(const LinePlot& plot) {
  std::vector<double> xs, ys;
  for (const auto& s : plot.series) {
    for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (drawable(s.x[i], plot.log_x) && drawable(s.y[i], plot.log_y)) {
        xs.push_back(s.x[i]);
        ys.push_back(s.y[i]);
      }
    }
  }
  if (xs.empty()) throw ValueError("plot '" + plot.title + "': nothing to draw");
  const Axis ax = make_axis(xs, plot.log_x), ay = make_axis(ys, plot.log_y);
  const double x0 = left, x1 = width - right, y0 = height - bottom, y1 = top;

  std::string svg =
      fmt::format("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" viewBox=\"0 0 {} {}\" "
                  "font-family=\"sans-serif\" font-size=\"12\">\n"
                  "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
                  "<text x=\"{:.1f}\" y=\"22\" text-anchor=\"middle\" font-size=\"15\">{}</text>\n",
                  width, height, width, height, (x0 + x1) / 2, escape_markup(plot.title));
  // Grid, ticks and labels.
  for (double t : ticks(ax)) {
    const double px = ax.map(t, x0, x1);
    svg += fmt::format("<line x1=\"{0:.2f}\" y1=\"{1:.2f}\" x2=\"{0:.2f}\" y2=\"{2:.2f}\" stroke=\"#e0e0e0\"/>\n", px,
                       y0, y1);
    svg += fmt::format("<text x=\"{:.2f}\" y=\"{:.2f}\" text-anchor=\"middle\">{}</text>\n", px, y0 + 16,
                       tick_label(t, ax.log));
  }
  for (double t : ticks(ay)) {
    const double py = ay.map(t, y0, y1);
    svg += fmt::format("<line x1=\"{0:.2f}\" y1=\"{1:.2f}\" x2=\"{2:.2f}\" y2=\"{1:.2f}\" stroke=\"#e0e0e0\"/>\n", x0,
                       py, x1);
    svg += fmt::format("<text x=\"{:.2f}\" y=\"{:.2f}\" text-anchor=\"end\">{}</text>\n", x0 - 6, py + 4,
                       tick_label(t, ay.log));
  }
  svg += fmt::format(
      "<rect x=\"{:.2f}\" y=\"{:.2f}\" width=\"{:.2f}\" height=\"{:.2f}\" fill=\"none\" stroke=\"black\"/>\n", x0, y1,
      x1 - x0, y0 - y1);
  svg += fmt::format("<text x=\"{:.2f}\" y=\"{:.2f}\" text-anchor=\"middle\">{}</text>\n", (x0 + x1) / 2, height - 18,
                     escape_markup(plot.x_label));
  svg += fmt::format("<text transform=\"translate(18 {:.2f}) rotate(-90)\" text-anchor=\"middle\">{}</text>\n",
                     (y0 + y1) / 2, escape_markup(plot.y_label));
  // Series and legend.
  for (std::size_t k = 0; k < plot.series.size(); ++k) {
    const PlotSeries& s = plot.series[k];
    const char* colour = palette[k % std::size(palette)];
    std::string points;
    std::string dots;
    for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!drawable(s.x[i], plot.log_x) || !drawable(s.y[i], plot.log_y)) continue;
      const double px = ax.map(s.x[i], x0, x1), py = ay.map(s.y[i], y0, y1);
      points += fmt::format("{:.2f},{:.2f} ", px, py);
      if (s.markers)
        dots += fmt::format("<circle cx=\"{:.2f}\" cy=\"{:.2f}\" r=\"2.5\" fill=\"{}\"/>\n", px, py, colour);
    }
    if (!points.empty()) points.pop_back();
    svg += fmt::format("<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"1.6\"{} points=\"{}\"/>\n", colour,
                       s.dashed ? " stroke-dasharray=\"6 4\"" : "", points);
    svg += dots;
    const double ly = y1 + 14 + 18 * static_cast<double>(k);
    svg += fmt::format(
        "<line x1=\"{:.2f}\" y1=\"{:.2f}\" x2=\"{:.2f}\" y2=\"{:.2f}\" stroke=\"{}\" stroke-width=\"2\"{}/>\n", x1 + 10,
        ly, x1 + 34, ly, colour, s.dashed ? " stroke-dasharray=\"6 4\"" : "");
    svg += fmt::format("<text x=\"{:.2f}\" y=\"{:.2f}\">{}</text>\n", x1 + 40, ly + 4, escape_markup(s.label));
  }
  svg += "</svg>\n";
  return svg;
}

}  // namespace pneuma::paper
