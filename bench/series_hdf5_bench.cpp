// series.h5's per-frame positions written with HDF5's plain API, layout and filters varied (#35):
// the demo's frames (rest + s_k u of `make demo`'s series.h5, or PNEUMA_BENCH_SERIES) written
// again into a fresh file per iteration, as the HDF5 sink does (no fsync). Baseline in the same
// run: `raw` (contiguous, no filter). Counters: file_MB, and vs_raw (its size / the raw file's).
//   per-frame: one (N, 3) dataset per frame (what XDMF readers take as plain geometry)
//   stacked:   one (F, N, 3) dataset, `frames` frames per chunk (XDMF would need a HyperSlab)
#include <benchmark/benchmark.h>
#include <hdf5.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

namespace {

struct Frames {
  hsize_t vertices = 0;
  std::vector<double> positions;  // frame-major: F x N x 3
  hsize_t count() const { return vertices == 0 ? 0 : positions.size() / (3 * vertices); }
};

std::vector<double> read_doubles(hid_t file, const char* name, hsize_t& rows) {
  const hid_t set = H5Dopen2(file, name, H5P_DEFAULT);
  if (set < 0) return {};
  const hid_t space = H5Dget_space(set);
  std::array<hsize_t, 2> dims{0, 1};
  const int rank = H5Sget_simple_extent_dims(space, dims.data(), nullptr);
  rows = dims[0];
  std::vector<double> values(dims[0] * (rank == 2 ? dims[1] : 1));
  H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
  H5Sclose(space);
  H5Dclose(set);
  return values;
}

// The demo's frames, computed in double as the runner does (rest + s u).
const Frames& demo_frames() {
  static const Frames frames = [] {
    Frames f;
    const char* env = std::getenv("PNEUMA_BENCH_SERIES");
    const std::string path = env ? env : PNEUMA_BENCH_SOURCE_DIR "/out/demo/series.h5";
    if (!std::filesystem::exists(path)) return f;
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (file < 0) return f;
    hsize_t n = 0, n_u = 0, count = 0;
    const std::vector<double> rest = read_doubles(file, "/rest/positions", n);
    const std::vector<double> u = read_doubles(file, "/field/unit_displacement", n_u);
    const std::vector<double> scale = read_doubles(file, "/frames/scale", count);
    H5Fclose(file);
    if (n == 0 || n_u != n) return f;
    f.vertices = n;
    f.positions.resize(count * n * 3);
    for (hsize_t k = 0; k < count; ++k)
      for (hsize_t i = 0; i < n * 3; ++i) f.positions[k * n * 3 + i] = rest[i] + scale[k] * u[i];
    return f;
  }();
  return frames;
}

enum Layout : int { per_frame = 0, stacked = 1 };

struct Variant {
  Layout layout = per_frame;
  bool float64 = false;
  bool shuffle = false;
  int level = 0;         // deflate level; 0: no filter
  hsize_t frames = 1;    // frames per chunk (stacked)
  bool chunked = false;  // per-frame: one chunk even without a filter
};

double write_file(const Frames& f, const Variant& v, const std::string& path) {
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  const hid_t type = v.float64 ? H5T_IEEE_F64LE : H5T_IEEE_F32LE;
  const hsize_t n = f.vertices, count = f.count();
  const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
  H5Pset_obj_track_times(dcpl, 0);
  const auto filters = [&](int rank, const hsize_t* chunk) {
    if (v.level > 0 || v.shuffle || v.chunked || (v.layout == stacked && v.frames > 0)) H5Pset_chunk(dcpl, rank, chunk);
    if (v.shuffle) H5Pset_shuffle(dcpl);
    if (v.level > 0) H5Pset_deflate(dcpl, static_cast<unsigned>(v.level));
  };
  const hid_t group = H5Gcreate2(file, "positions", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (v.layout == per_frame) {
    const std::array<hsize_t, 2> dims{n, 3};
    filters(2, dims.data());
    const hid_t space = H5Screate_simple(2, dims.data(), nullptr);
    for (hsize_t k = 0; k < count; ++k) {
      const std::string name = std::to_string(1000000 + k).substr(1);
      const hid_t set = H5Dcreate2(group, name.c_str(), type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
      H5Dwrite(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, f.positions.data() + k * n * 3);
      H5Dclose(set);
    }
    H5Sclose(space);
  } else {
    const std::array<hsize_t, 3> dims{count, n, 3};
    const std::array<hsize_t, 3> chunk{v.frames, n, 3};
    filters(3, chunk.data());
    const hid_t space = H5Screate_simple(3, dims.data(), nullptr);
    // A chunk cache that holds a whole chunk: without it every frame's write compresses its
    // partly filled chunk again (HDF5's default cache is 1 MiB).
    const hid_t dapl = H5Pcreate(H5P_DATASET_ACCESS);
    const std::size_t chunk_bytes = std::max<hsize_t>(1, v.frames) * n * 3 * (v.float64 ? 8 : 4);
    H5Pset_chunk_cache(dapl, 521, 2 * chunk_bytes, 1.0);
    const hid_t set = H5Dcreate2(group, "all", type, space, H5P_DEFAULT, dcpl, dapl);
    H5Pclose(dapl);
    // Frame by frame, as the sink receives them.
    const std::array<hsize_t, 3> one{1, n, 3};
    const hid_t memory = H5Screate_simple(3, one.data(), nullptr);
    for (hsize_t k = 0; k < count; ++k) {
      const std::array<hsize_t, 3> start{k, 0, 0};
      H5Sselect_hyperslab(space, H5S_SELECT_SET, start.data(), nullptr, one.data(), nullptr);
      H5Dwrite(set, H5T_NATIVE_DOUBLE, memory, space, H5P_DEFAULT, f.positions.data() + k * n * 3);
    }
    H5Sclose(memory);
    H5Dclose(set);
    H5Sclose(space);
  }
  H5Gclose(group);
  H5Pclose(dcpl);
  H5Fclose(file);
  return static_cast<double>(std::filesystem::file_size(path));
}

double raw_size() {
  static const double size = [] {
    const std::string path = (std::filesystem::temp_directory_path() / "pneuma-series-bench-raw.h5").string();
    const double s = write_file(demo_frames(), {}, path);
    std::filesystem::remove(path);
    return s;
  }();
  return size;
}

// Args: layout, float64, shuffle, deflate level, frames per chunk (stacked) or 1 = chunked (per-frame).
void BM_SeriesWrite(benchmark::State& state) {
  const Frames& f = demo_frames();
  if (f.count() == 0) {
    state.SkipWithError("no series.h5: run `make demo` first or set PNEUMA_BENCH_SERIES");
    return;
  }
  Variant v;
  v.layout = static_cast<Layout>(state.range(0));
  v.float64 = state.range(1) != 0;
  v.shuffle = state.range(2) != 0;
  v.level = static_cast<int>(state.range(3));
  v.frames = static_cast<hsize_t>(state.range(4));
  v.chunked = v.layout == per_frame && state.range(4) == 1;
  const std::string path = (std::filesystem::temp_directory_path() / "pneuma-series-bench.h5").string();
  double size = 0.0;
  for (auto _ : state) size = write_file(f, v, path);
  std::filesystem::remove(path);
  state.counters["file_MB"] = size / 1e6;
  state.counters["vs_raw"] = size / raw_size();
  state.counters["frames"] = static_cast<double>(f.count());
  state.counters["vertices"] = static_cast<double>(f.vertices);
}

void variants(benchmark::internal::Benchmark* b) {
  b->ArgNames({"layout", "f64", "shuffle", "gzip", "chunk"});
  b->Args({stacked, 0, 0, 0, 0});  // raw, one contiguous (F, N, 3) dataset
  for (int f64 : {0, 1}) {
    b->Args({per_frame, f64, 0, 0, 0});  // raw, contiguous
    b->Args({per_frame, f64, 0, 0, 1});  // one chunk, no filter
    b->Args({per_frame, f64, 0, 1, 1});
    b->Args({per_frame, f64, 1, 1, 1});
    b->Args({per_frame, f64, 1, 4, 1});  // the sink before #35
    b->Args({per_frame, f64, 1, 6, 1});
  }
  for (int frames : {1, 16, 128}) {
    b->Args({stacked, 0, 1, 1, frames});
    b->Args({stacked, 0, 1, 4, frames});
  }
}
BENCHMARK(BM_SeriesWrite)->Apply(variants)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);

}  // namespace

BENCHMARK_MAIN();
