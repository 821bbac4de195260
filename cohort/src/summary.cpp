#include "pneuma/cohort/summary.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/markup.h"
#include "pneuma/core/paths.h"
#include "pneuma/mesh/anatomy/regions.h"

namespace pneuma::cohort {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

std::optional<double> number(const std::string& text) {
  if (text.empty()) return std::nullopt;
  try {
    std::size_t used = 0;
    const double v = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(v)) return std::nullopt;
    return v;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// The mean of column `name` of a CSV file over the rows `keep` accepts (all by default); none
// when the file or the column is missing or no row has a value.
std::optional<double> csv_mean(
    const fs::path& file, const std::string& name,
    const std::function<bool(const std::vector<std::string>&, const std::vector<std::string>&)>& keep = nullptr) {
  std::ifstream in(file);
  std::string line;
  if (!in || !std::getline(in, line)) return std::nullopt;
  const std::vector<std::string> header = split_csv_line(line);
  const auto column = std::find(header.begin(), header.end(), name);
  if (column == header.end()) return std::nullopt;
  const auto index = static_cast<std::size_t>(column - header.begin());
  double sum = 0.0;
  std::size_t count = 0;
  while (std::getline(in, line)) {
    const std::vector<std::string> cells = split_csv_line(line);
    if (index >= cells.size() || (keep && !keep(header, cells))) continue;
    if (auto v = number(cells[index])) {
      sum += *v;
      ++count;
    }
  }
  if (count == 0) return std::nullopt;
  return sum / static_cast<double>(count);
}

// Snakemake's benchmark file: a header, then `s  h:m:s  max_rss ...` of the job (wall seconds).
std::optional<double> benchmark_seconds(const fs::path& file) {
  std::ifstream in(file);
  std::string header, values;
  if (!in || !std::getline(in, header) || !std::getline(in, values)) return std::nullopt;
  return number(values.substr(0, values.find('\t')));
}

std::string read_text_or_empty(const fs::path& file) {
  try {
    return read_file_bytes(file);
  } catch (const Error&) {
    return {};
  }
}

// A failed job's log: its one-line error (the last line before "exit status N" that is not a
// warning) and N. Without that last line the job did not finish (it was killed).
struct LogOutcome {
  bool exists = false;
  std::optional<int> exit_code;
  std::string error;
};

LogOutcome read_log(const fs::path& file) {
  LogOutcome outcome;
  if (!path_exists(file)) return outcome;
  outcome.exists = true;
  std::vector<std::string> lines;
  std::istringstream in(read_text_or_empty(file));
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!line.empty()) lines.push_back(line);
  }
  const std::string prefix = "exit status ";
  if (!lines.empty() && lines.back().rfind(prefix, 0) == 0) {
    outcome.exit_code = static_cast<int>(number(lines.back().substr(prefix.size())).value_or(1));
    lines.pop_back();
  }
  for (auto it = lines.rbegin(); it != lines.rend(); ++it) {
    if (it->rfind("pneuma: warning:", 0) != 0) {
      outcome.error = *it;
      break;
    }
  }
  return outcome;
}

std::optional<double> fact(const nlohmann::json& facts, const std::string& key, double scale = 1.0) {
  if (!facts.contains(key) || !facts.at(key).is_string()) return std::nullopt;
  const auto v = number(facts.at(key).get<std::string>());
  if (!v) return std::nullopt;
  return *v * scale;
}

const std::vector<std::string> kRegionValues = {"caudal_mean_mm", "magnitude_mean_mm", "magnitude_max_mm",
                                                "volume_share_pct"};

std::vector<std::string> make_columns() {
  std::vector<std::string> c = {"vertices",          "triangles", "frames",          "rest_volume_mL",
                                "rest_area_cm2",     "breaths",   "tidal_volume_mL", "mesh_volume_change_mL",
                                "dome_top_caudal_mm"};
  for (mesh::Region region : mesh::kRegions) {
    for (const auto& value : kRegionValues) c.push_back(std::string(mesh::region_name(region)) + "_" + value);
  }
  for (const char* timing : {"field_wall_s", "run_wall_s", "run_compute_s"}) c.emplace_back(timing);
  return c;
}

std::size_t column_index(const std::string& name) {
  const auto& columns = summary_columns();
  return static_cast<std::size_t>(std::find(columns.begin(), columns.end(), name) - columns.begin());
}

void read_run(const fs::path& dir, const fs::path& relative_run_dir, Row& row) {
  const fs::path run_dir = dir / relative_run_dir;
  auto set = [&](const std::string& column, std::optional<double> value) { row.values[column_index(column)] = value; };
  nlohmann::json manifest;
  try {
    manifest = nlohmann::json::parse(read_file_bytes(run_dir / "manifest.json"));
  } catch (const std::exception& e) {
    row.status = "failed";
    row.error = (run_dir / "manifest.json").string() + ": cannot be read: " + e.what();
    return;
  }
  const nlohmann::json facts = manifest.value("facts", nlohmann::json::object());
  set("vertices", fact(facts, "vertices"));
  set("triangles", fact(facts, "triangles"));
  set("frames", fact(facts, "frames"));
  set("rest_volume_mL", fact(facts, "rest_volume_m3", 1e6));
  set("rest_area_cm2", fact(facts, "rest_area_m2", 1e4));
  set("breaths", fact(facts, "motion.breaths"));
  set("dome_top_caudal_mm", fact(facts, "motion.dome_top_caudal_mm"));
  for (mesh::Region region : mesh::kRegions) {
    const std::string name(mesh::region_name(region));
    for (const auto& value : kRegionValues)
      set(fmt::format("{}_{}", name, value), fact(facts, fmt::format("motion.{}.{}", name, value)));
  }
  set("tidal_volume_mL", csv_mean(run_dir / "physiology-breaths.csv", "tidal_volume_mL"));
  // motion.csv repeats each breath's volume change on each of its region rows: one per breath.
  const std::string first_region(mesh::region_name(mesh::kRegions.front()));
  set("mesh_volume_change_mL",
      csv_mean(run_dir / "motion.csv", "breath_volume_change_mL",
               [&](const std::vector<std::string>& header, const std::vector<std::string>& cells) {
                 const auto r = std::find(header.begin(), header.end(), "region") - header.begin();
                 return static_cast<std::size_t>(r) < cells.size() &&
                        cells[static_cast<std::size_t>(r)] == first_region;
               }));
  double compute = 0.0;
  const nlohmann::json timings = manifest.value("timings_s", nlohmann::json::object());
  for (const auto& [stage, seconds] : timings.items()) {
    if (seconds.is_number()) compute += seconds.get<double>();
  }
  set("run_compute_s", compute);
  const nlohmann::json files = manifest.value("files", nlohmann::json::array());
  for (const auto& file : files) {
    if (file.value("path", "") == "report.html") row.report = (relative_run_dir / "report.html").generic_string();
  }
}

std::string csv_quote(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string out = "\"";
  for (char c : text) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string format_value(const std::optional<double>& v) { return v ? fmt::format("{:.9g}", *v) : ""; }

// ---- cohort.html ----

double nice_step(double range) {
  const double raw = range / 5.0;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0}) {
    if (raw <= m * magnitude) return m * magnitude;
  }
  return 10.0 * magnitude;
}

double quantile(std::vector<double> sorted, double q) {
  const double at = q * static_cast<double>(sorted.size() - 1);
  const auto i = static_cast<std::size_t>(std::floor(at));
  const std::size_t j = std::min(i + 1, sorted.size() - 1);
  return sorted[i] + (at - static_cast<double>(i)) * (sorted[j] - sorted[i]);
}

struct PlotMetric {
  const char* column;
  const char* title;
};

// One metric across subjects: a row per scenario, each subject a point (linking to its run's
// report.html, its name and value in the tooltip) over the box of its quartiles and median.
// A subject's colour class ("s0" .. "s9", in the order subjects first appear): the same in every
// plot and in the legend; beyond ten subjects colours repeat and the hover title tells them apart.
constexpr std::size_t kSubjectColours = 10;
std::string subject_class(const std::vector<std::string>& subjects, const std::string& subject) {
  const auto at = static_cast<std::size_t>(std::find(subjects.begin(), subjects.end(), subject) - subjects.begin());
  return fmt::format("s{}", at % kSubjectColours);
}

std::string strip_plot(const std::vector<Row>& rows, const std::vector<std::string>& scenarios,
                       const std::vector<std::string>& subjects, const PlotMetric& metric) {
  const std::size_t index = column_index(metric.column);
  double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  for (const Row& r : rows) {
    if (auto v = r.values[index]) {
      lo = std::min(lo, *v);
      hi = std::max(hi, *v);
    }
  }
  if (!(lo <= hi)) return {};
  if (hi - lo < 1e-12 * std::max(1.0, std::abs(hi))) {
    lo -= std::max(1.0, std::abs(lo) * 0.05);
    hi += std::max(1.0, std::abs(hi) * 0.05);
  }
  const double step = nice_step(hi - lo);
  const double axis_lo = std::floor(lo / step) * step, axis_hi = std::ceil(hi / step) * step;
  const double left = 170, right = 700, row_height = 34, top = 10;
  const double height = top + row_height * static_cast<double>(scenarios.size()) + 30;
  auto x = [&](double v) { return left + (v - axis_lo) / (axis_hi - axis_lo) * (right - left); };
  std::string svg =
      fmt::format("<figure><figcaption>{}</figcaption>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"720\" "
                  "height=\"{:.0f}\" role=\"img\">\n",
                  escape_markup(metric.title), height);
  const double axis_y = top + row_height * static_cast<double>(scenarios.size());
  svg += fmt::format("<line x1=\"{}\" y1=\"{:.1f}\" x2=\"{}\" y2=\"{:.1f}\" class=\"axis\"/>\n", left, axis_y, right,
                     axis_y);
  for (double t = axis_lo; t <= axis_hi + step * 1e-9; t += step) {
    svg += fmt::format(
        "<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{0:.1f}\" y2=\"{2:.1f}\" class=\"grid\"/><text x=\"{0:.1f}\" "
        "y=\"{3:.1f}\" class=\"tick\">{4:.6g}</text>\n",
        x(t), top, axis_y + 4, axis_y + 18, t);
  }
  for (std::size_t s = 0; s < scenarios.size(); ++s) {
    const double y = top + row_height * (static_cast<double>(s) + 0.5);
    svg += fmt::format("<text x=\"{}\" y=\"{:.1f}\" class=\"label\">{}</text>\n", left - 8, y + 4,
                       escape_markup(scenarios[s]));
    std::vector<double> values;
    for (const Row& r : rows) {
      if (r.scenario == scenarios[s] && r.values[index]) values.push_back(*r.values[index]);
    }
    if (values.empty()) continue;
    std::sort(values.begin(), values.end());
    const double q1 = quantile(values, 0.25), median = quantile(values, 0.5), q3 = quantile(values, 0.75);
    svg += fmt::format("<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" class=\"whisker\"/>"
                       "<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" class=\"box\"/>"
                       "<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" class=\"median\"/>\n",
                       x(values.front()), y, x(values.back()), y, x(q1), y - 9, std::max(1.0, x(q3) - x(q1)), 18.0,
                       x(median), y - 9, x(median), y + 9);
    std::size_t k = 0;
    for (const Row& r : rows) {
      if (r.scenario != scenarios[s] || !r.values[index]) continue;
      const double jitter = (static_cast<double>(k++ % 5) - 2.0) * 3.0;
      const std::string point = fmt::format(
          "<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"4\" class=\"point {}\"><title>{} ({}): {:.6g}</title></circle>",
          x(*r.values[index]), y + jitter, subject_class(subjects, r.subject), escape_markup(r.subject),
          escape_markup(r.scenario), *r.values[index]);
      svg += r.report.empty() ? point + "\n" : fmt::format("<a href=\"{}\">{}</a>\n", escape_markup(r.report), point);
    }
  }
  return svg + "</svg></figure>\n";
}

constexpr PlotMetric kPlots[] = {
    {"rest_volume_mL", "Rest volume of the surface (mL)"},
    {"tidal_volume_mL", "Mean tidal volume (mL)"},
    {"mesh_volume_change_mL", "Mean volume change of the surface per breath (mL)"},
    {"dome_top_caudal_mm", "Dome top, caudal motion per breath (mm)"},
    {"diaphragmatic_caudal_mean_mm", "Diaphragmatic region, mean caudal motion (mm)"},
    {"apex_caudal_mean_mm", "Apex, mean caudal motion (mm)"},
    {"costal_magnitude_mean_mm", "Costal region, mean displacement (mm)"},
    {"mediastinal_magnitude_mean_mm", "Mediastinal region, mean displacement (mm)"},
    {"diaphragmatic_volume_share_pct", "Diaphragmatic share of the volume change (%)"},
    {"field_wall_s", "Field job, wall time (s)"},
    {"run_wall_s", "Run job, wall time (s)"},
};

std::string html_page(const std::string& name, const std::vector<Row>& rows) {
  std::vector<std::string> scenarios, subjects;
  std::map<std::string, int> statuses;
  for (const Row& r : rows) {
    if (std::find(scenarios.begin(), scenarios.end(), r.scenario) == scenarios.end()) scenarios.push_back(r.scenario);
    if (std::find(subjects.begin(), subjects.end(), r.subject) == subjects.end()) subjects.push_back(r.subject);
    ++statuses[r.status];
  }
  std::string counts;
  for (const auto& [status, n] : statuses) counts += fmt::format("{}{} {}", counts.empty() ? "" : ", ", n, status);
  std::string page = fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{0} - pneuma cohort</title>\n"
      "<style>body{{font-family:sans-serif;margin:1.5em;color:#222}}table{{border-collapse:collapse;font-size:13px}}"
      "td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}td.t,th.t{{text-align:left;white-space:nowrap}}"
      "tr.failed td{{background:#fde8e8}}figure{{margin:1em 0}}figcaption{{font-weight:bold}}"
      ".axis{{stroke:#444}}.grid{{stroke:#ddd}}.tick{{font-size:11px;text-anchor:middle;fill:#444}}"
      ".label{{font-size:12px;text-anchor:end}}.box{{fill:#cfe0f3;stroke:#3a6ea5}}.median{{stroke:#1d3d63;"
      "stroke-width:2}}.whisker{{stroke:#3a6ea5}}.point{{fill-opacity:.85;stroke:#fff}}"
      ".s0{{fill:#1f77b4;background:#1f77b4}}.s1{{fill:#ff7f0e;background:#ff7f0e}}.s2{{fill:#2ca02c;"
      "background:#2ca02c}}.s3{{fill:#d62728;background:#d62728}}.s4{{fill:#9467bd;background:#9467bd}}"
      ".s5{{fill:#8c564b;background:#8c564b}}.s6{{fill:#e377c2;background:#e377c2}}.s7{{fill:#7f7f7f;"
      "background:#7f7f7f}}.s8{{fill:#bcbd22;background:#bcbd22}}.s9{{fill:#17becf;background:#17becf}}"
      ".legend span{{margin-right:1em;white-space:nowrap}}.dot{{display:inline-block;width:10px;height:10px;"
      "border-radius:50%;margin-right:4px}}.scroll{{overflow-x:auto;max-width:100%}}</style>\n"
      "</head><body>\n<h1>Cohort {0}</h1>\n<p>{1} subjects &times; {2} scenarios: {3} runs ({4}). Each point is a "
      "subject, coloured as in the legend (hover for its name, click for its run's report.html); the box spans the quartiles, the bar is the "
      "median, the line the range.</p>\n",
      escape_markup(name), subjects.size(), scenarios.size(), rows.size(), escape_markup(counts));
  std::string failures;
  for (const Row& r : rows) {
    if (r.status == "ok") continue;
    failures += fmt::format(
        "<tr class=\"failed\"><td class=\"t\">{}</td><td class=\"t\">{}</td><td class=\"t\">{}</td><td>{}</td>"
        "<td class=\"t\">{}</td><td class=\"t\">{}</td></tr>\n",
        escape_markup(r.subject), escape_markup(r.scenario), escape_markup(r.status),
        r.exit_code ? std::to_string(*r.exit_code) : "", escape_markup(r.error),
        r.log.empty() ? "" : fmt::format("<a href=\"{0}\">{0}</a>", escape_markup(r.log)));
  }
  if (!failures.empty()) {
    page +=
        "<h2>Runs that did not complete</h2>\n<div class=\"scroll\"><table><tr><th class=\"t\">subject</th><th class=\"t\">scenario</th>"
        "<th class=\"t\">status</th><th>exit</th><th class=\"t\">error</th><th class=\"t\">log</th></tr>\n" +
        failures + "</table></div>\n";
  }
  page += "<h2>Distributions across subjects</h2>\n<p class=\"legend\">";
  for (const std::string& subject : subjects) {
    page += fmt::format("<span><span class=\"dot {}\"></span>{}</span>", subject_class(subjects, subject),
                        escape_markup(subject));
  }
  page += "</p>\n";
  for (const PlotMetric& metric : kPlots) page += strip_plot(rows, scenarios, subjects, metric);
  // The tables scroll inside their own box: a column per metric is wider than most windows.
  page +=
      "<h2>Every run</h2>\n<div class=\"scroll\"><table><tr><th class=\"t\">subject</th><th class=\"t\">scenario</th>"
      "<th class=\"t\">status</th>";
  for (const PlotMetric& metric : kPlots) page += fmt::format("<th>{}</th>", escape_markup(metric.column));
  page += "<th class=\"t\">report</th></tr>\n";
  for (const Row& r : rows) {
    page += fmt::format("<tr{}><td class=\"t\">{}</td><td class=\"t\">{}</td><td class=\"t\">{}</td>",
                        r.status == "ok" ? "" : " class=\"failed\"", escape_markup(r.subject),
                        escape_markup(r.scenario), escape_markup(r.status));
    for (const PlotMetric& metric : kPlots) {
      const auto& v = r.values[column_index(metric.column)];
      page += fmt::format("<td>{}</td>", v ? fmt::format("{:.4g}", *v) : "");
    }
    page += fmt::format("<td class=\"t\">{}</td></tr>\n",
                        r.report.empty() ? "" : fmt::format("<a href=\"{0}\">{0}</a>", escape_markup(r.report)));
  }
  return page + "</table></div>\n<p>Data: cohort.csv beside this page. Written by pneuma " PNEUMA_VERSION
                ".</p>\n</body></html>\n";
}

}  // namespace

const std::vector<std::string>& summary_columns() {
  static const std::vector<std::string> columns = make_columns();
  return columns;
}

std::vector<Row> read_rows(const fs::path& dir, const Plan& plan) {
  std::vector<Row> rows;
  for (const RunJob& run : plan.runs) {
    Row row;
    row.subject = run.subject;
    row.scenario = run.scenario;
    row.values.assign(summary_columns().size(), std::nullopt);
    const fs::path run_dir = fs::path("runs") / run.subject / run.scenario;
    const fs::path run_log = fs::path("logs/runs") / run.subject / (run.scenario + ".log");
    const fs::path field_file = fs::path("fields") / run.subject / (run.field + ".h5");
    const fs::path field_log = fs::path("logs/fields") / run.subject / (run.field + ".log");
    row.values[column_index("field_wall_s")] =
        benchmark_seconds(dir / "benchmarks/fields" / run.subject / (run.field + ".tsv"));
    if (path_exists(dir / run_dir / "manifest.json")) {
      row.status = "ok";
      row.exit_code = 0;
      row.values[column_index("run_wall_s")] =
          benchmark_seconds(dir / "benchmarks/runs" / run.subject / (run.scenario + ".tsv"));
      read_run(dir, run_dir, row);
    } else if (const LogOutcome log = read_log(dir / run_log); log.exists) {
      row.status = log.exit_code ? "failed" : "incomplete";
      row.exit_code = log.exit_code;
      row.error = log.error;
      row.log = run_log.generic_string();
    } else if (const LogOutcome flog = read_log(dir / field_log); flog.exists && !path_exists(dir / field_file)) {
      row.status = flog.exit_code ? "field failed" : "incomplete";
      row.exit_code = flog.exit_code;
      row.error = flog.error;
      row.log = field_log.generic_string();
    } else {
      row.status = "not run";
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

void write_summary(const fs::path& dir, const std::string& cohort_name, const std::vector<Row>& rows) {
  write_stream_atomically(dir / "cohort.csv", false, [&](std::ostream& out) {
    out << "subject,scenario,status,exit_code";
    for (const auto& column : summary_columns()) out << ',' << column;
    out << ",report,log,error\n";
    for (const Row& r : rows) {
      out << csv_quote(r.subject) << ',' << csv_quote(r.scenario) << ',' << csv_quote(r.status) << ','
          << (r.exit_code ? std::to_string(*r.exit_code) : "");
      for (const auto& v : r.values) out << ',' << format_value(v);
      out << ',' << csv_quote(r.report) << ',' << csv_quote(r.log) << ',' << csv_quote(r.error) << '\n';
    }
  });
  write_stream_atomically(dir / "cohort.html", false, [&](std::ostream& out) { out << html_page(cohort_name, rows); });
}

}  // namespace pneuma::cohort
