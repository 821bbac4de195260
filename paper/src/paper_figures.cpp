// The paper's evaluation, experiment by experiment (see paper_figures.h and
// docs/paper-reproduction.md for what each one means and what it shows).
#include "pneuma/paper/paper_figures.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <numeric>
#include <ostream>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/field/field_graph.h"
#include "pneuma/field/field_solver.h"
#include "pneuma/paper/comparators.h"

namespace pneuma::paper {
namespace {

std::string num(double v) { return fmt::format("{:.9g}", v); }
std::string num(std::uint64_t v) { return fmt::format("{}", v); }

double mean(const std::vector<double>& v) {
  return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}
double stddev(const std::vector<double>& v) {
  if (v.size() < 2) return 0.0;
  const double m = mean(v);
  double s = 0.0;
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}

// The set-up of figures 6 - 8: a square lattice pushed at its centre vertex.
struct PushSetup {
  std::uint32_t side, centre, probe;
  LinkGraph graph;
  std::vector<double> mu;  // uniform: the regular grid of the paper is isotropic
  std::unique_ptr<field::FieldGraph> field;
  std::shared_ptr<const field::TransferOperator> one_hop;
  std::vector<double> load;

  explicit PushSetup(const ReproductionOptions& o) : side(o.grid_side) {
    if (side < 3 || side % 2 == 0) throw ValueError("grid side must be odd and at least 3");
    centre = (side / 2) * side + side / 2;
    const std::uint32_t offset = std::min(o.probe_offset, side / 2);
    probe = centre + offset;
    graph = square_lattice(side);
    mu.assign(graph.vertex_count(), 1e3);
    field = std::make_unique<field::FieldGraph>(link_mesh(graph), mu);
    one_hop = std::make_shared<const field::TransferOperator>(field::one_hop_operator(*field));
    load.assign(graph.vertex_count(), 0.0);
    load[centre] = 1.0;
  }
};

std::vector<double> normalised(const std::vector<double>& v, std::size_t at) {
  std::vector<double> out(v);
  const double s = v[at];
  for (double& x : out) x /= s;
  return out;
}

ComparatorOptions comparator_options(const ReproductionOptions& o, std::int64_t probe = -1) {
  ComparatorOptions c;
  c.tolerance = o.tolerance;
  c.probe_vertex = probe;
  return c;
}

// Operations (and steps) until the probe stays within `band` of its final value.
std::pair<std::uint64_t, std::uint64_t> settle(const ConvergenceTrace& t, double band) {
  const double final_value = t.probe.back();
  std::size_t first = t.probe.size() - 1;
  for (std::size_t i = t.probe.size(); i-- > 0;) {
    if (std::abs(t.probe[i] - final_value) > band * std::abs(final_value)) break;
    first = i;
  }
  return {t.step[first], t.operations[first]};
}

PlotSeries trace_series(const std::string& label, const ConvergenceTrace& t, bool residual, double probe_scale = 1.0,
                        bool dashed = false) {
  PlotSeries s;
  s.label = label;
  s.dashed = dashed;
  for (std::size_t i = 0; i < t.step.size(); ++i) {
    s.x.push_back(static_cast<double>(t.operations[i]));
    s.y.push_back(residual ? t.residual[i] : t.probe[i] / probe_scale);
  }
  return s;
}

void add_trace_rows(FigureOutput& f, const std::string& method, const ConvergenceTrace& t, double probe_scale) {
  for (std::size_t i = 0; i < t.step.size(); ++i)
    f.rows.push_back({method, num(t.step[i]), num(t.operations[i]), num(t.residual[i]), num(t.probe[i] / probe_scale)});
}

std::uint64_t total(const field::OperationCounts& c) { return c.additions + c.multiplications; }

}  // namespace

ReproductionOptions quick_reproduction_options() {
  ReproductionOptions o;
  o.grid_side = 11;
  o.probe_offset = 2;
  o.fig2_sides = {5, 9, 17, 33};
  o.seeds = 4;
  o.table1_sides = {16, 32, 64};
  return o;
}

double log_log_slope(const std::vector<double>& x, const std::vector<double>& y) {
  std::vector<double> lx, ly;
  for (std::size_t i = 0; i < x.size() && i < y.size(); ++i) {
    if (x[i] > 0.0 && y[i] > 0.0) {
      lx.push_back(std::log(x[i]));
      ly.push_back(std::log(y[i]));
    }
  }
  if (lx.size() < 2) throw ValueError("log-log slope: need two or more positive pairs");
  const double mx = mean(lx), my = mean(ly);
  double sxx = 0.0, sxy = 0.0;
  for (std::size_t i = 0; i < lx.size(); ++i) {
    sxx += (lx[i] - mx) * (lx[i] - mx);
    sxy += (lx[i] - mx) * (ly[i] - my);
  }
  if (!(sxx > 0.0)) throw ValueError("log-log slope: the x values must differ");
  return sxy / sxx;
}

// ---- Figure 6: displacement per vertex, proposed against mass-spring --------------------------

FigureOutput figure6(const ReproductionOptions& o) {
  const PushSetup s(o);
  const ComparatorOptions co = comparator_options(o);
  const ComparatorResult proposed = Proposed_Santhanam(s.one_hop).solve(s.load, co);
  const ComparatorResult matched = MassSpring_Witkin(matched_network(*s.field), o.tolerance).solve(s.load, co);
  const ComparatorResult clamped =
      MassSpring_Witkin(clamped_network(s.graph, s.mu, lattice_border(s.side)), o.tolerance).solve(s.load, co);
  const auto p = normalised(proposed.displacement, s.centre);
  const auto m = normalised(matched.displacement, s.centre);
  const auto c = normalised(clamped.displacement, s.centre);

  FigureOutput f;
  f.name = "fig6";
  f.columns = {"vertex",
               "row",
               "column",
               "proposed",
               "mass_spring_matched",
               "mass_spring_clamped",
               "difference_matched",
               "difference_clamped"};
  double max_dm = 0.0, max_dc = 0.0, ss_dc = 0.0;
  std::uint32_t worst_c = 0;
  for (std::uint32_t v = 0; v < s.graph.vertex_count(); ++v) {
    const double dm = p[v] - m[v], dc = p[v] - c[v];
    max_dm = std::max(max_dm, std::abs(dm));
    if (std::abs(dc) > max_dc) {
      max_dc = std::abs(dc);
      worst_c = v;
    }
    ss_dc += dc * dc;
    f.rows.push_back({num(std::uint64_t{v}), num(std::uint64_t{v / s.side}), num(std::uint64_t{v % s.side}), num(p[v]),
                      num(m[v]), num(c[v]), num(dm), num(dc)});
  }
  f.plot.title = fmt::format("Figure 6: {0}x{0} grid pushed at its centre", s.side);
  f.plot.x_label = "vertex (row-wise numbering)";
  f.plot.y_label = "displacement / displacement of the pushed vertex";
  auto series = [&](const std::string& label, const std::vector<double>& y, bool dashed) {
    PlotSeries ps;
    ps.label = label;
    ps.dashed = dashed;
    for (std::uint32_t v = 0; v < y.size(); ++v) {
      ps.x.push_back(v);
      ps.y.push_back(y[v]);
    }
    f.plot.series.push_back(std::move(ps));
  };
  std::vector<double> dc(p.size()), dm(p.size());
  for (std::size_t v = 0; v < p.size(); ++v) {
    dc[v] = p[v] - c[v];
    dm[v] = p[v] - m[v];
  }
  series("proposed", p, false);
  series("mass-spring, clamped", c, false);
  series("mass-spring, matched", m, true);
  series("proposed - clamped", dc, true);
  const std::uint32_t next = s.centre + 1, quarter = std::max<std::uint32_t>(2, s.side / 4);
  f.summary = {
      fmt::format("fig6: {0}x{0} lattice ({1} vertices), unit push at vertex {2}; displacements divided by the pushed "
                  "vertex's",
                  s.side, s.graph.vertex_count(), s.centre),
      fmt::format("fig6: proposed vs mass-spring matched to the field's equations: max |difference| {:.3g}", max_dm),
      fmt::format("fig6: proposed vs clamped mass-spring membrane: max |difference| {:.3g} (vertex {}), RMS {:.3g}",
                  max_dc, worst_c, std::sqrt(ss_dc / static_cast<double>(p.size()))),
      fmt::format("fig6: the pushed vertex's neighbour moves {:.3g} (proposed), {:.3g} (clamped membrane) of the "
                  "push; the vertex {} links away {:.3g} and {:.3g}",
                  p[next], c[next], quarter, p[s.centre + quarter], c[s.centre + quarter]),
  };
  return f;
}

// ---- Figure 7: convergence, proposed against mass-spring ----------------------------------------

FigureOutput figure7(const ReproductionOptions& o) {
  const PushSetup s(o);
  const ComparatorOptions co = comparator_options(o, s.centre);
  const ComparatorResult proposed = Proposed_Santhanam(s.one_hop).solve(s.load, co);
  const MassSpring_Witkin matched_ms(matched_network(*s.field), o.tolerance);
  const MassSpring_Witkin clamped_ms(clamped_network(s.graph, s.mu, lattice_border(s.side)), o.tolerance);
  const ComparatorResult matched = matched_ms.solve(s.load, co);
  const ComparatorResult clamped = clamped_ms.solve(s.load, co);

  // The exact fixed point (sparse LU) tells how far the stopped Shot/UnShot is from it.
  std::vector<double> node_load(s.field->node_count(), 0.0);
  node_load[s.centre] = 1.0;
  const field::SolveResult exact = field::Direct_Eigen(s.one_hop).solve(node_load);
  double proposed_error = 0.0;
  for (std::uint32_t v = 0; v < s.graph.vertex_count(); ++v)
    proposed_error = std::max(proposed_error, std::abs(proposed.displacement[v] - exact.shot[v]));

  FigureOutput f;
  f.name = "fig7";
  f.columns = {"method", "step", "operations", "residual", "pushed_vertex_displacement"};
  add_trace_rows(f, "proposed", proposed.trace, 1.0);
  add_trace_rows(f, "mass_spring_matched", matched.trace, 1.0);
  add_trace_rows(f, "mass_spring_clamped", clamped.trace, 1.0);
  f.plot.title = fmt::format("Figure 7: convergence, {0}x{0} grid pushed at its centre", s.side);
  f.plot.x_label = "work: additions + multiplications";
  f.plot.y_label = "max residual / max load";
  f.plot.log_x = f.plot.log_y = true;
  f.plot.series = {trace_series("proposed (Shot/UnShot)", proposed.trace, true),
                   trace_series("mass-spring, matched", matched.trace, true),
                   trace_series("mass-spring, clamped", clamped.trace, true)};
  auto describe = [&](const char* label, const MassSpring_Witkin& ms, const ComparatorResult& r) {
    const EulerStepChoice& c = ms.step_choice();
    return fmt::format(
        "fig7: {}: {} explicit Euler steps ({:.3g} predicted), {} operations; lambda in [{:.4g}, {:.4g}] "
        "(Gershgorin bound {:.4g}), damping {:.4g}, step {:.4g} = {:.2f} x the stability limit {:.4g} "
        "(Gershgorin-only limit {:.4g}); contraction {:.6f} per step; simulated time {:.4g}",
        label, r.steps, c.predicted_steps, total(r.counts), c.lambda_min, c.lambda_max, c.gershgorin_max, c.damping,
        c.step, c.step / c.stable_step, c.stable_step, c.gershgorin_step, c.contraction,
        c.step * static_cast<double>(r.steps));
  };
  const double nodes = static_cast<double>(s.field->node_count());
  f.summary = {
      fmt::format("fig7: tolerance {:g} on max residual / max load for every method", o.tolerance),
      fmt::format("fig7: proposed: {} shots (= {:.2f} shots per graph node, {} mass + {} spring nodes), {} operations; "
                  "max error against the exact fixed point {:.3g}",
                  proposed.steps, static_cast<double>(proposed.steps) / nodes, s.field->mass_count(),
                  s.field->spring_count(), total(proposed.counts), proposed_error),
      describe("mass-spring matched", matched_ms, matched),
      describe("mass-spring clamped", clamped_ms, clamped),
      fmt::format("fig7: work ratio mass-spring / proposed: matched {:.1f}x, clamped {:.1f}x",
                  static_cast<double>(total(matched.counts)) / static_cast<double>(total(proposed.counts)),
                  static_cast<double>(total(clamped.counts)) / static_cast<double>(total(proposed.counts))),
  };
  return f;
}

// ---- Figure 8: convergence of one vertex, proposed against exponential ---------------------------

FigureOutput figure8(const ReproductionOptions& o) {
  const PushSetup s(o);
  const ComparatorOptions co = comparator_options(o, s.probe);
  const ComparatorResult proposed = Proposed_Santhanam(s.one_hop).solve(s.load, co);
  const ComparatorResult sweeps = CumulativeSweeps(s.one_hop, "proposed-sweeps").solve(s.load, co);
  const ComparatorResult hauth = Exponential_Hauth(s.graph, s.mu).solve(s.load, co);

  FigureOutput f;
  f.name = "fig8";
  f.columns = {"method", "step", "operations", "residual", "probe_over_final"};
  const double fp = proposed.trace.probe.back(), fs = sweeps.trace.probe.back(), fh = hauth.trace.probe.back();
  add_trace_rows(f, "proposed", proposed.trace, fp);
  add_trace_rows(f, "proposed_sweeps", sweeps.trace, fs);
  add_trace_rows(f, "exponential", hauth.trace, fh);
  f.plot.title = fmt::format("Figure 8: vertex {} ({} links from the push)", s.probe, s.probe - s.centre);
  f.plot.x_label = "work: additions + multiplications";
  f.plot.y_label = "displacement / its final value";
  f.plot.log_x = true;
  f.plot.series = {trace_series("proposed (Shot/UnShot)", proposed.trace, false, fp),
                   trace_series("proposed kernel, sweeps", sweeps.trace, false, fs, true),
                   trace_series("exponential (Hauth)", hauth.trace, false, fh)};
  auto line = [&](const char* label, const ComparatorResult& r, const char* unit) {
    const auto [step1, ops1] = settle(r.trace, 0.01);
    return fmt::format("fig8: {}: within 1% of its final value after {} {} ({} operations); converged after {} {} "
                       "({} operations)",
                       label, step1, unit, ops1, r.steps, unit, total(r.counts));
  };
  // How far apart the two kernels' shapes are (each divided by its pushed vertex).
  const auto pn = normalised(proposed.displacement, s.centre), hn = normalised(hauth.displacement, s.centre);
  double shape = 0.0;
  for (std::size_t v = 0; v < pn.size(); ++v) shape = std::max(shape, std::abs(pn[v] - hn[v]));
  f.summary = {line("proposed", proposed, "shots"), line("proposed kernel in sweeps", sweeps, "sweeps"),
               line("exponential (Hauth)", hauth, "sweeps"),
               fmt::format("fig8: probe / pushed vertex: proposed {:.4g}, exponential {:.4g}; max shape difference "
                           "{:.3g}",
                           pn[s.probe], hn[s.probe], shape)};
  return f;
}

// ---- Figure 2: regular against irregular grids ---------------------------------------------------

FigureOutput figure2(const ReproductionOptions& o) {
  FigureOutput f;
  f.name = "fig2";
  f.columns = {"side",
               "vertices",
               "links_removed_fraction",
               "node_rms_variation",
               "node_rms_variation_sd",
               "normalised_node_rms_variation",
               "mean_variation",
               "mean_variation_sd",
               "max_node_variation"};
  PlotSeries node_series{"per-vertex RMS", {}, {}, false, true};
  PlotSeries normalised_series{"per-vertex RMS, same mean", {}, {}, false, true};
  PlotSeries mean_series{"change of the mean", {}, {}, true, true};
  PlotSeries scatter_series{"seed-to-seed sd of mean", {}, {}, true, true};
  std::vector<double> sizes, node_means, global_means, normalised_means, scatter;
  const field::SolveOptions solve{1e-10};
  for (std::uint32_t side : o.fig2_sides) {
    const LinkGraph regular = square_lattice(side);
    const std::vector<double> mu(regular.vertex_count(), 1e3);
    const std::vector<double> load(regular.vertex_count(), 1.0);  // the lung's pressure: the same on every vertex
    auto field_of = [&](const LinkGraph& g) {
      return field::ConjugateGradient_Schur(std::make_shared<const field::FieldGraph>(link_mesh(g), mu), solve)
          .solve(load)
          .shot;
    };
    const std::vector<double> reference = field_of(regular);
    const double reference_mean = mean(reference);
    std::vector<double> node_rms, normalised_rms, global, removed;
    double max_node = 0.0;
    for (std::uint32_t k = 0; k < o.seeds; ++k) {
      const LinkGraph irregular = remove_links(regular, o.link_removal, o.seed * 1'000'003ULL + side * 1009ULL + k);
      const std::vector<double> field = field_of(irregular);
      double ss = 0.0;
      for (std::size_t v = 0; v < field.size(); ++v) {
        const double d = field[v] - reference[v];
        ss += d * d;
        max_node = std::max(max_node, std::abs(d) / reference_mean);
      }
      node_rms.push_back(std::sqrt(ss / static_cast<double>(field.size())) / reference_mean);
      // The pipeline normalises every field to one area unit (METHOD.md 4), which on a flat grid
      // is a common factor: compare the shapes with the same mean as well.
      const double rescale = reference_mean / mean(field);
      double ss_normalised = 0.0;
      for (std::size_t v = 0; v < field.size(); ++v) {
        const double d = rescale * field[v] - reference[v];
        ss_normalised += d * d;
      }
      normalised_rms.push_back(std::sqrt(ss_normalised / static_cast<double>(field.size())) / reference_mean);
      global.push_back(std::abs(mean(field) - reference_mean) / reference_mean);
      removed.push_back(1.0 - static_cast<double>(irregular.links.size()) / static_cast<double>(regular.links.size()));
    }
    const double n = regular.vertex_count();
    f.rows.push_back({num(std::uint64_t{side}), num(std::uint64_t{regular.vertex_count()}), num(mean(removed)),
                      num(mean(node_rms)), num(stddev(node_rms)), num(mean(normalised_rms)), num(mean(global)),
                      num(stddev(global)), num(max_node)});
    node_series.x.push_back(n);
    node_series.y.push_back(mean(node_rms));
    normalised_series.x.push_back(n);
    normalised_series.y.push_back(mean(normalised_rms));
    mean_series.x.push_back(n);
    mean_series.y.push_back(mean(global));
    scatter_series.x.push_back(n);
    scatter_series.y.push_back(stddev(global));
    sizes.push_back(n);
    node_means.push_back(mean(node_rms));
    normalised_means.push_back(mean(normalised_rms));
    global_means.push_back(mean(global));
    scatter.push_back(stddev(global));
  }
  f.plot.title = fmt::format("Figure 2: regular vs irregular grids (links removed, p = {:g})", o.link_removal);
  f.plot.x_label = "number of vertices";
  f.plot.y_label = "variation / mean displacement";
  f.plot.log_x = f.plot.log_y = true;
  f.plot.series = {node_series, normalised_series, mean_series, scatter_series};
  f.summary = {
      fmt::format("fig2: uniform load, {} seeds per size, sizes {} to {} vertices", o.seeds, sizes.front(),
                  sizes.back()),
      fmt::format("fig2: per-vertex RMS variation {:.3g} -> {:.3g} (log-log slope {:.3f})", node_means.front(),
                  node_means.back(), sizes.size() > 1 ? log_log_slope(sizes, node_means) : 0.0),
      fmt::format("fig2: per-vertex RMS variation with both fields scaled to the same mean {:.3g} -> {:.3g} "
                  "(log-log slope {:.3f})",
                  normalised_means.front(), normalised_means.back(),
                  sizes.size() > 1 ? log_log_slope(sizes, normalised_means) : 0.0),
      fmt::format("fig2: change of the mean displacement {:.3g} -> {:.3g} (log-log slope {:.3f})", global_means.front(),
                  global_means.back(), sizes.size() > 1 ? log_log_slope(sizes, global_means) : 0.0),
      fmt::format("fig2: seed-to-seed standard deviation of that change {:.3g} -> {:.3g} (log-log slope {:.3f})",
                  scatter.front(), scatter.back(), sizes.size() > 1 ? log_log_slope(sizes, scatter) : 0.0),
  };
  return f;
}

// ---- Table 1: counted operations against N and M --------------------------------------------------

FigureOutput table1(const ReproductionOptions& o) {
  FigureOutput f;
  f.name = "table1";
  f.columns = {"side",
               "N",
               "M",
               "operator_entries",
               "shots",
               "additions",
               "multiplications",
               "build_additions",
               "build_multiplications"};
  std::map<int, std::vector<double>> n_of, add_of, mul_of, build_of;
  for (std::uint32_t side : o.table1_sides) {
    const LinkGraph g = square_lattice(side);
    const std::vector<double> mu(g.vertex_count(), 1e3);
    const field::FieldGraph fg(link_mesh(g), mu);
    std::vector<double> load(fg.node_count(), 0.0);
    std::fill(load.begin(), load.begin() + fg.mass_count(), 1.0);
    for (int m = 1; m <= o.max_clique; ++m) {
      auto op = m == 1 ? std::make_shared<const field::TransferOperator>(field::one_hop_operator(fg))
                       : std::make_shared<const field::TransferOperator>(field::clique_operator(fg, m));
      const field::SolveResult r = field::ShotUnshot_Santhanam(op, field::SolveOptions{o.tolerance}, true).solve(load);
      const double n = fg.mass_count();
      f.rows.push_back({num(std::uint64_t{side}), num(std::uint64_t{fg.mass_count()}), num(std::uint64_t(m)),
                        num(op->entry_count()), num(r.report.shots), num(r.report.counts.additions),
                        num(r.report.counts.multiplications), num(op->build_counts.additions),
                        num(op->build_counts.multiplications)});
      n_of[m].push_back(n);
      add_of[m].push_back(static_cast<double>(r.report.counts.additions));
      mul_of[m].push_back(static_cast<double>(r.report.counts.multiplications));
      build_of[m].push_back(static_cast<double>(op->build_counts.multiplications));
    }
  }
  f.plot.title = "Table 1: counted operations of Shot/UnShot";
  f.plot.x_label = "N (mass nodes)";
  f.plot.y_label = "operations";
  f.plot.log_x = f.plot.log_y = true;
  std::vector<double> ms, mul_per_n, add_per_n;
  for (int m = 1; m <= o.max_clique; ++m) {
    f.plot.series.push_back({fmt::format("M={} multiplications", m), n_of[m], mul_of[m], false, true});
    f.plot.series.push_back({fmt::format("M={} additions", m), n_of[m], add_of[m], true, false});
    const bool fit = n_of[m].size() > 1;
    f.summary.push_back(fmt::format(
        "table1: M={}: slope in N: additions {:.3f}, multiplications {:.3f}; per mass node at N={}: {:.1f} additions, "
        "{:.1f} multiplications (building the clique: {:.1f} multiplications per node)",
        m, fit ? log_log_slope(n_of[m], add_of[m]) : 0.0, fit ? log_log_slope(n_of[m], mul_of[m]) : 0.0, n_of[m].back(),
        add_of[m].back() / n_of[m].back(), mul_of[m].back() / n_of[m].back(), build_of[m].back() / n_of[m].back()));
    ms.push_back(m);
    mul_per_n.push_back(mul_of[m].back() / n_of[m].back());
    add_per_n.push_back(add_of[m].back() / n_of[m].back());
  }
  if (ms.size() > 1) {
    f.summary.push_back(fmt::format("table1: slope in M at the largest N: additions per node {:.3f}, "
                                    "multiplications per node {:.3f} (the paper: 0 and 1)",
                                    log_log_slope(ms, add_per_n), log_log_slope(ms, mul_per_n)));
  }
  return f;
}

// ---- Names, dispatch, files ------------------------------------------------------------------------

const std::vector<std::string>& figure_names() {
  static const std::vector<std::string> names{"fig2", "fig6", "fig7", "fig8", "table1"};
  return names;
}

FigureOutput run_figure(const std::string& name, const ReproductionOptions& options) {
  if (name == "fig2") return figure2(options);
  if (name == "fig6") return figure6(options);
  if (name == "fig7") return figure7(options);
  if (name == "fig8") return figure8(options);
  if (name == "table1") return table1(options);
  throw ValueError("unknown figure '" + name + "'");
}

std::vector<std::filesystem::path> write_figure(const FigureOutput& figure, const std::filesystem::path& dir) {
  const auto csv = dir / (figure.name + ".csv");
  const auto svg = dir / (figure.name + ".svg");
  write_stream_atomically(csv, false, [&](std::ostream& out) {
    for (std::size_t i = 0; i < figure.columns.size(); ++i) out << (i ? "," : "") << figure.columns[i];
    out << '\n';
    for (const auto& row : figure.rows) {
      for (std::size_t i = 0; i < row.size(); ++i) out << (i ? "," : "") << row[i];
      out << '\n';
    }
  });
  const std::string text = render_svg(figure.plot);
  write_stream_atomically(svg, false, [&](std::ostream& out) { out << text; });
  return {csv, svg};
}

}  // namespace pneuma::paper
