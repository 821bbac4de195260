// The field's precomputation against mesh size (10k, 100k, 1M vertices) for every solver, at the
// same tolerance, in one run; and the clique sizes M = 1..4 with measured operation counts
// (the paper's Table 1). Results: BENCHMARKS.md, section "Field".
//
// Meshes: geodesic spheres of frequency n (each icosahedron face cut into n^2 triangles,
// 10 n^2 + 2 vertices), which give vertex counts close to round numbers, unlike icospheres.
#include <benchmark/benchmark.h>

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>
#include <chrono>
#include <cmath>
#include <map>

#include "pneuma/field/field.h"
#include "pneuma/field/field_graph.h"
#include "pneuma/field/field_solver.h"

namespace {

using namespace pneuma;
using namespace pneuma::field;
constexpr double kTolerance = 1e-6;

mesh::TriangleMesh geodesic_sphere(double radius, int n) {
  const double phi = (1.0 + std::sqrt(5.0)) / 2.0;
  const std::vector<Eigen::Vector3d> corner = {{-1, phi, 0}, {1, phi, 0}, {-1, -phi, 0}, {1, -phi, 0},
                                               {0, -1, phi}, {0, 1, phi}, {0, -1, -phi}, {0, 1, -phi},
                                               {phi, 0, -1}, {phi, 0, 1}, {-phi, 0, -1}, {-phi, 0, 1}};
  const std::vector<std::array<int, 3>> face = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                                {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                                {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                                {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  std::map<std::pair<int, int>, int> edge_id;
  for (const auto& f : face) {
    for (int k = 0; k < 3; ++k) {
      const auto key = std::minmax(f[k], f[(k + 1) % 3]);
      edge_id.emplace(key, static_cast<int>(edge_id.size()));
    }
  }
  const std::size_t per_edge = n - 1, per_face = static_cast<std::size_t>(n - 1) * (n - 2) / 2;
  mesh::TriangleMesh m;
  m.vertices.resize(12 + 30 * per_edge + 20 * per_face);
  std::vector<char> placed(m.vertices.size(), 0);
  std::vector<std::vector<std::uint32_t>> local(n + 1, std::vector<std::uint32_t>(n + 1, 0));
  std::uint32_t count = 0;
  for (int i = 1; i < n; ++i) {
    for (int j = 1; i + j < n; ++j) local[i][j] = count++;
  }
  for (std::size_t f = 0; f < face.size(); ++f) {
    const int a = face[f][0], b = face[f][1], c = face[f][2];
    auto index = [&](int i, int j) -> std::uint32_t {
      const int w[3] = {n - i - j, i, j};
      const int id[3] = {a, b, c};
      int nonzero = 0;
      for (int k : w) nonzero += k > 0;
      std::size_t v;
      if (nonzero == 1) {
        v = static_cast<std::size_t>(w[0] ? a : w[1] ? b : c);
      } else if (nonzero == 2) {
        int u = -1, x = -1, wu = 0, wx = 0;
        for (int k = 0; k < 3; ++k) {
          if (!w[k]) continue;
          if (u < 0) {
            u = id[k];
            wu = w[k];
          } else {
            x = id[k];
            wx = w[k];
          }
        }
        const int step = u < x ? wx : wu;  // distance from the smaller corner
        v = 12 + edge_id.at(std::minmax(u, x)) * per_edge + (step - 1);
      } else {
        v = 12 + 30 * per_edge + f * per_face + local[i][j];
      }
      if (!placed[v]) {
        placed[v] = 1;
        const Eigen::Vector3d p = (corner[a] * (n - i - j) + corner[b] * i + corner[c] * j) / n;
        m.vertices[v] = radius * p.normalized();
      }
      return static_cast<std::uint32_t>(v);
    };
    for (int i = 0; i < n; ++i) {
      for (int j = 0; i + j < n; ++j) {
        m.triangles.push_back({index(i, j), index(i + 1, j), index(i, j + 1)});
        if (i + j < n - 1) m.triangles.push_back({index(i + 1, j), index(i + 1, j + 1), index(i, j + 1)});
      }
    }
  }
  return m;
}

// Frequencies for ~10k, ~100k and ~1M vertices.
int frequency_for(int vertices_k) { return vertices_k == 10 ? 32 : vertices_k == 100 ? 100 : 316; }

struct Mesh {
  mesh::TriangleMesh mesh;
  std::vector<double> mu;
};
const Mesh& test_mesh(int vertices_k) {
  static std::map<int, Mesh> cache;
  auto it = cache.find(vertices_k);
  if (it == cache.end()) {
    Mesh m{geodesic_sphere(0.1, frequency_for(vertices_k)), {}};
    // healthy-upright: 2.4 kPa at the apex (top) to 0.6 kPa at the base, linear in height.
    for (const auto& v : m.mesh.vertices) m.mu.push_back(600.0 + 1800.0 * (v.z() / 0.1 + 1.0) / 2.0);
    it = cache.emplace(vertices_k, std::move(m)).first;
  }
  return it->second;
}

// The whole precomputation: graph, solver set-up, solve, normalisation.
void BM_Field(benchmark::State& state, SolverKind kind) {
  const Mesh& m = test_mesh(static_cast<int>(state.range(0)));
  FieldOptions o;
  o.solver = kind;
  o.tolerance = kTolerance;
  ElastostaticField f;
  for (auto _ : state) {
    f = compute_field(m.mesh, m.mu, o);
    benchmark::DoNotOptimize(f.unit_displacement.data());
  }
  state.counters["vertices"] = static_cast<double>(m.mesh.vertex_count());
  state.counters["nodes"] = f.mass_nodes + f.spring_nodes;
  state.counters["graph_s"] = f.graph_seconds;
  state.counters["solve_s"] = f.report.seconds;
  state.counters["shots"] = static_cast<double>(f.report.shots);
  state.counters["iterations"] = static_cast<double>(f.report.iterations);
  state.counters["residual"] = f.report.residual;
}

// Eigen's conjugate gradients on the same symmetric Schur system as ConjugateGradient_Schur
// (the best Eigen solver for this fixed point), with the same stopping bound and the same
// graph build and normalisation around it, so its time compares with BM_Field/cg: ||S r||_inf <=
// tol * max f follows from ||r||_2 <= tol * max f / max S.
void BM_FieldEigenCG(benchmark::State& state) {
  const Mesh& m = test_mesh(static_cast<int>(state.range(0)));
  double iterations = 0;
  for (auto _ : state) {
    const FieldGraph g(m.mesh, m.mu);
    const std::uint32_t nv = g.mass_count();
    const auto& s = g.weight();
    const auto& z = g.normaliser();
    const auto& gf = g.distance_factor();
    std::vector<Eigen::Triplet<double>> t;
    t.reserve(nv + 2 * g.spring_count());
    std::vector<double> diag(nv);
    for (std::uint32_t i = 0; i < nv; ++i) diag[i] = z[i] / s[i];
    for (std::uint32_t e = 0; e < g.spring_count(); ++e) {
      const double w = gf[e] * gf[e] * s[nv + e] / z[nv + e];
      const auto [a, b] = g.edges()[e];
      diag[a] -= w;
      diag[b] -= w;
      t.emplace_back(a, b, -w);
      t.emplace_back(b, a, -w);
    }
    for (std::uint32_t i = 0; i < nv; ++i) t.emplace_back(i, i, diag[i]);
    Eigen::SparseMatrix<double, Eigen::RowMajor> k(nv, nv);
    k.setFromTriplets(t.begin(), t.end());
    Eigen::VectorXd b(nv);
    double max_s = 0.0;
    for (std::uint32_t i = 0; i < nv; ++i) {
      b[i] = 1.0 / s[i];
      max_s = std::max(max_s, s[i]);
    }
    Eigen::ConjugateGradient<Eigen::SparseMatrix<double, Eigen::RowMajor>, Eigen::Lower | Eigen::Upper> cg(k);
    cg.setTolerance(kTolerance / max_s / b.norm());
    const Eigen::VectorXd y = cg.solve(b);
    std::vector<double> force(nv);
    for (std::uint32_t i = 0; i < nv; ++i) force[i] = s[i] * y[i];  // F = S y
    const auto u = normalise_displacement(m.mesh, force, 1e-4);     // as compute_field does
    benchmark::DoNotOptimize(u.first.data());
    iterations = static_cast<double>(cg.iterations());
  }
  state.counters["iterations"] = iterations;
}

// Table 1: build the clique operator of M hops and run Shot/UnShot on it with counters on;
// report additions and multiplications (build + shots) per mass node and the distance of the
// normalised field from M = 1.
void BM_Clique(benchmark::State& state) {
  const int hops = static_cast<int>(state.range(0));
  const mesh::TriangleMesh m = mesh::make_icosphere(0.1, static_cast<int>(state.range(1)));
  std::vector<double> mu;
  for (const auto& v : m.vertices) mu.push_back(600.0 + 1800.0 * (v.z() / 0.1 + 1.0) / 2.0);
  const FieldGraph g(m, mu);
  std::vector<double> load(g.node_count(), 0.0);
  std::fill(load.begin(), load.begin() + g.mass_count(), 1.0);
  auto field_of = [&](const SolveResult& r) {
    return normalise_displacement(m, std::span<const double>(r.shot.data(), g.mass_count()), 1e-4).first;
  };
  const auto reference =
      field_of(ShotUnshot_Santhanam(std::make_shared<const TransferOperator>(one_hop_operator(g)), SolveOptions{1e-9})
                   .solve(load));
  OperationCounts build, shots;
  double difference = 0.0, shot_count = 0.0;
  for (auto _ : state) {
    auto op = std::make_shared<const TransferOperator>(clique_operator(g, hops));
    const SolveResult r = ShotUnshot_Santhanam(op, SolveOptions{kTolerance}, true).solve(load);
    build = op->build_counts;
    shots = r.report.counts;
    shot_count = static_cast<double>(r.report.shots);
    const auto u = field_of(r);
    double worst = 0.0, largest = 0.0;
    for (std::size_t i = 0; i < u.size(); ++i) {
      worst = std::max(worst, (u[i] - reference[i]).norm());
      largest = std::max(largest, reference[i].norm());
    }
    difference = worst / largest;
  }
  const double n = g.mass_count();
  state.counters["mass_nodes"] = n;
  state.counters["shots"] = shot_count;
  state.counters["build_add_per_node"] = static_cast<double>(build.additions) / n;
  state.counters["build_mul_per_node"] = static_cast<double>(build.multiplications) / n;
  state.counters["shot_add_per_node"] = static_cast<double>(shots.additions) / n;
  state.counters["shot_mul_per_node"] = static_cast<double>(shots.multiplications) / n;
  state.counters["max_rel_diff_from_M1"] = difference;
}

}  // namespace

BENCHMARK_CAPTURE(BM_Field, cg, SolverKind::cg)
    ->Arg(10)
    ->Arg(100)
    ->Arg(1000)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);
// One run in a process that has not run any other field: memory first touched (page faults
// cost ~4 s/GB on this VM). Run alone: --benchmark_filter=BM_Field/cg_first_run
BENCHMARK_CAPTURE(BM_Field, cg_first_run, SolverKind::cg)->Arg(1000)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_FieldEigenCG)->Arg(10)->Arg(100)->Arg(1000)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK_CAPTURE(BM_Field, direct, SolverKind::direct)
    ->Arg(10)
    ->Arg(100)
    ->Arg(1000)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);
BENCHMARK_CAPTURE(BM_Field, sweep, SolverKind::sweep)
    ->Arg(10)
    ->Arg(100)
    ->Arg(1000)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);
BENCHMARK_CAPTURE(BM_Field, shot, SolverKind::shot)
    ->Arg(10)
    ->Arg(100)
    ->Arg(1000)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);
BENCHMARK(BM_Clique)->ArgsProduct({{1, 2, 3, 4}, {3, 4, 5}})->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK_MAIN();
