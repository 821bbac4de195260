#include "pneuma/outputs/report.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <string_view>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/core/markup.h"
#include "pneuma/core/units.h"
#include "report_assets.h"

namespace pneuma::outputs {
namespace {

using Json = nlohmann::ordered_json;

constexpr double kMl = units::ml_per_m3;
constexpr double kLitre = units::litres_per_m3;
constexpr double kCmH2O = units::cmh2o_per_pa;

// x rounded to `decimals` decimals: the page needs no more, and JSON then prints it short.
double rounded(double x, int decimals) {
  const double f = std::pow(10.0, decimals);
  const double r = std::round(x * f) / f;
  return r == 0.0 ? 0.0 : r;  // no "-0.0"
}

// A number for the page, or null where the breath has none (NaN: no hold, no effort, no circuit).
Json number_or_null(double x, int decimals) { return std::isfinite(x) ? Json(rounded(x, decimals)) : Json(nullptr); }

// The ventilator screen's numerics of each breath (report.js shows the one under the cursor), as a
// ventilator shows them: the breath's own pressures and volumes, and the rates and expired minute
// volume over the minute before the breath's end (the run so far during its first minute).
Json ventilator_screen(const std::vector<physiology::BreathMetrics>& breaths) {
  Json screen = Json::array();
  for (std::size_t i = 0; i < breaths.size(); ++i) {
    const auto& b = breaths[i];
    const double end = b.start_s + b.duration_s, window = std::min(60.0, end);
    double expired = 0.0;
    int total = 0, spontaneous = 0;
    for (std::size_t j = 0; j <= i; ++j) {
      const auto& o = breaths[j];
      if (!(o.start_s + o.duration_s > end - window)) continue;
      ++total;
      if (std::string_view(o.breath_type) == "spontaneous") ++spontaneous;
      if (std::isfinite(o.vte_m3)) expired += o.vte_m3;
    }
    const double te = b.duration_s - b.inspiratory_time_s;
    screen.push_back(Json{
        {"pip", number_or_null(b.peak_pressure_pa * kCmH2O, 1)},
        {"pplat", number_or_null(b.plateau_pressure_pa * kCmH2O, 1)},
        {"pmean", number_or_null(b.mean_airway_pressure_pa * kCmH2O, 1)},
        {"peep", number_or_null(b.peep_pa * kCmH2O, 1)},
        {"peepi", number_or_null(b.intrinsic_peep_pa * kCmH2O, 1)},
        {"vti", number_or_null(b.vti_m3 * kMl, 0)},
        {"vte", number_or_null(b.vte_m3 * kMl, 0)},
        {"mve", number_or_null(expired * kLitre / window * 60.0, 2)},
        {"rr", number_or_null(total * 60.0 / window, 1)},
        {"rr_spont", number_or_null(spontaneous * 60.0 / window, 1)},
        {"ie", number_or_null(b.inspiratory_time_s > 0.0 ? te / b.inspiratory_time_s : NAN, 2)},  // 1 : this
        {"cdyn", number_or_null(b.dynamic_compliance_m3_per_pa * kMl / kCmH2O, 1)},
        {"leak", number_or_null(b.vti_m3 > 0.0 ? (b.vti_m3 - b.vte_m3) / b.vti_m3 * 100.0 : NAN, 0)},
        {"alarms", b.alarms},
    });
  }
  return screen;
}

std::string base64(std::string_view bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  auto byte = [&](std::size_t k) { return static_cast<unsigned>(static_cast<unsigned char>(bytes[k])); };
  for (; i + 3 <= bytes.size(); i += 3) {
    const unsigned v = byte(i) << 16 | byte(i + 1) << 8 | byte(i + 2);
    for (int shift : {18, 12, 6, 0}) out += kAlphabet[(v >> shift) & 63];
  }
  if (const std::size_t rest = bytes.size() - i; rest > 0) {
    const unsigned v = byte(i) << 16 | (rest == 2 ? byte(i + 1) << 8 : 0u);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += rest == 2 ? kAlphabet[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

// JSON inside <script>: no '<' at all (strings are the only place one can be), so neither
// "</script>" nor "<!--" can end or bend the element.
std::string script_json(const Json& j) {
  const std::string text = j.dump(-1, ' ', false, Json::error_handler_t::replace);
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    if (c == '<') {
      out += "\\u003c";
    } else {
      out += c;
    }
  }
  return out;
}

// A script inlined as is: it must not contain its own end tag.
std::string_view inline_script(std::string_view name, std::string_view text) {
  for (std::size_t at = text.find("</"); at != std::string_view::npos; at = text.find("</", at + 2)) {
    std::string tag(text.substr(at + 2, 6));
    for (char& c : tag) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (tag == "script") throw Error(ExitCode::failure, std::string(name) + ": contains </script>; cannot inline it");
  }
  return text;
}

// The physiology columns of physiology.csv, every stride-th sample and the last, and the plots.
void add_series(Json& data, const physiology::SimulationResult& result, std::size_t stride) {
  const auto& s = result.series;
  std::vector<std::size_t> keep;
  for (std::size_t k = 0; k < s.size(); k += stride) keep.push_back(k);
  if (keep.back() != s.size() - 1) keep.push_back(s.size() - 1);
  auto column = [&](const std::vector<double>& values, double factor, int decimals) {
    Json a = Json::array();
    for (std::size_t k : keep) a.push_back(rounded(values[k] * factor, decimals));
    return a;
  };
  Json columns = Json::object();
  Json labels = Json::object();
  columns["time_s"] = column(s.time_s, 1.0, 6);
  columns["volume_mL"] = column(s.volume_m3, kMl, 3);
  labels["volume_mL"] = "lung";
  const bool regional = result.compartment_names.size() > 1;
  std::vector<std::string> volumes{"volume_mL"};
  if (regional) {
    for (std::size_t c = 0; c < result.compartment_names.size(); ++c) {
      const std::string key = "volume_" + result.compartment_names[c] + "_mL";
      columns[key] = column(s.compartment_volume_m3[c], kMl, 3);
      labels[key] = result.compartment_names[c];
      volumes.push_back(key);
    }
  }
  columns["flow_L_per_s"] = column(s.flow_m3_per_s, kLitre, 5);
  labels["flow_L_per_s"] = "flow";
  const std::array<std::pair<const char*, const std::vector<double>*>, 4> pressures{{
      {"airway", &s.airway_pressure_pa},
      {"alveolar", &s.alveolar_pressure_pa},
      {"pleural", &s.pleural_pressure_pa},
      {"muscle", &s.muscle_pressure_pa},
  }};
  std::vector<std::string> pressure_keys;
  bool pressures_vary = false;
  for (const auto& [name, values] : pressures) {
    // A measured trace knows no pressures but the airway's (NaN): no curve rather than a false one.
    if (std::none_of(values->begin(), values->end(), [](double p) { return std::isfinite(p); })) continue;
    const auto [lo, hi] = std::minmax_element(values->begin(), values->end());
    pressures_vary = pressures_vary || *lo != *hi;
    const std::string key = std::string(name) + "_pressure_cmH2O";
    columns[key] = column(*values, kCmH2O, 4);
    labels[key] = name;
    pressure_keys.push_back(key);
  }
  data["series"] =
      Json{{"rows", s.size()}, {"stride", stride}, {"samples", keep.size()}, {"labels", labels}, {"columns", columns}};
  data["plots"] = Json::array({
      Json{{"title", "Volume above FRC"}, {"unit", "mL"}, {"columns", volumes}},
      Json{{"title", "Flow"}, {"unit", "L/s"}, {"columns", {"flow_L_per_s"}}},
  });
  // No empty or flat panel: a measured trace knows no pressure but the open airway's 0.
  if (pressures_vary)
    data["plots"].push_back(Json{{"title", "Pressures"}, {"unit", "cmH2O"}, {"columns", pressure_keys}});
  // Ventilated runs: the pressure-volume and flow-volume loops of the breath under the cursor.
  const bool ventilated = std::any_of(result.breaths.begin(), result.breaths.end(),
                                      [](const physiology::BreathMetrics& b) { return *b.trigger != '\0'; });
  if (ventilated) {
    Json starts = Json::array();
    for (const auto& b : result.breaths) starts.push_back(rounded(b.start_s, 6));
    const auto& last = result.breaths.back();
    starts.push_back(rounded(last.start_s + last.duration_s, 6));  // the end of the last complete breath
    data["loops"] = Json{{"breath_starts", starts}, {"screen", ventilator_screen(result.breaths)}};
  }
}

// The motion table: each region's motion, averaged over the completed breaths.
Json motion_json(const std::vector<BreathMotion>& motion) {
  Json regions = Json::array();
  const double n = static_cast<double>(motion.size());
  double dome = 0.0;
  for (const BreathMotion& b : motion) dome += b.summary.dome_top_caudal_m / n;
  for (mesh::Region region : mesh::kRegions) {
    const auto i = static_cast<std::size_t>(region);
    auto mean = [&](double mesh::RegionMotion::*field, double factor, int decimals) {
      double sum = 0.0;
      for (const BreathMotion& b : motion) sum += b.summary.region[i].*field;
      return motion.empty() ? 0.0 : rounded(sum / n * factor, decimals);
    };
    regions.push_back(Json{{"name", std::string(mesh::region_name(region))},
                           {"area_cm2", mean(&mesh::RegionMotion::area_m2, 1e4, 3)},
                           {"caudal_mean_mm", mean(&mesh::RegionMotion::caudal_mean_m, 1e3, 4)},
                           {"caudal_max_mm", mean(&mesh::RegionMotion::caudal_max_m, 1e3, 4)},
                           {"anterior_mean_mm", mean(&mesh::RegionMotion::anterior_mean_m, 1e3, 4)},
                           {"lateral_mean_mm", mean(&mesh::RegionMotion::lateral_mean_m, 1e3, 4)},
                           {"magnitude_mean_mm", mean(&mesh::RegionMotion::magnitude_mean_m, 1e3, 4)},
                           {"magnitude_max_mm", mean(&mesh::RegionMotion::magnitude_max_m, 1e3, 4)},
                           {"volume_share_pct", mean(&mesh::RegionMotion::volume_share, 100.0, 3)}});
  }
  return Json{{"breaths", motion.size()}, {"dome_top_caudal_mm", rounded(dome * 1e3, 4)}, {"regions", regions}};
}

// The bins: per bin its phase, frames and mean volume; per frame its bin.
Json bins_json(const ReportBins& bins) {
  Json rows = Json::array();
  for (std::size_t b = 0; b < bins.centre_percent.size(); ++b) {
    const double mean = bins.mean_volume_m3[b];
    rows.push_back(Json{{"percent", rounded(bins.centre_percent[b], 3)},
                        {"frames", bins.frames[b]},
                        {"mean_volume_mL", std::isfinite(mean) ? Json(rounded(mean * kMl, 2)) : Json(nullptr)}});
  }
  return Json{{"method", bins.method}, {"bins", rows}, {"bin_of_frame", bins.bin_of_frame}};
}

// A slice's labels run-length encoded, row by row as stored: [label, count, label, count, ...]
// (a lung plane is a few runs a row: tens of kB instead of megabytes).
template <typename Labels>
Json run_lengths(const Labels& labels) {
  Json out = Json::array();
  for (std::size_t i = 0; i < labels.size();) {
    std::size_t j = i;
    while (j < labels.size() && labels[j] == labels[i]) ++j;
    out.push_back(labels[i]);
    out.push_back(j - i);
    i = j;
  }
  return out;
}

// Each structure's masks on the plane (per time) and its ITV (null without one), run-length encoded.
Json plane_structures(const LabelSlice& slice) {
  Json out = Json::array();
  for (const LabelSlice::Structure& s : slice.structures) {
    Json masks = Json::array();
    for (const auto& mask : s.masks) masks.push_back(run_lengths(mask));
    out.push_back(Json{{"name", s.name}, {"masks", masks}, {"itv", s.itv.empty() ? Json() : run_lengths(s.itv)}});
  }
  return out;
}

Json slices_json(const std::vector<LabelSlice>& slices, const std::vector<int>& lung_labels) {
  Json planes = Json::array();
  for (const LabelSlice& slice : slices) {
    Json times = Json::array(), images = Json::array();
    for (std::size_t t = 0; t < slice.times_s.size(); ++t) {
      times.push_back(rounded(slice.times_s[t], 6));
      images.push_back(run_lengths(slice.labels[t]));
    }
    Json channels = Json::array(), channel_times = Json::array();
    for (const double t : slice.channel_times_s) channel_times.push_back(rounded(t, 6));
    for (const LabelSlice::Channel& c : slice.channels) {
      Json encoded = Json::array();  // one base64 string of bytes per channel time
      for (const auto& image : c.images)
        encoded.push_back(base64(std::string_view(reinterpret_cast<const char*>(image.data()), image.size())));
      channels.push_back(Json{{"name", c.name},
                              {"unit", c.unit},
                              {"lo", rounded(c.lo, 6)},
                              {"hi", rounded(c.hi, 6)},
                              {"log", c.log},
                              {"images", encoded}});
    }
    planes.push_back(Json{
        {"name", slice.name},
        {"fixed", slice.fixed},
        {"width", slice.width},
        {"height", slice.height},
        {"pixel_mm", rounded(slice.pixel_mm, 4)},
        {"origin_mm", {rounded(slice.origin_mm[0], 4), rounded(slice.origin_mm[1], 4), rounded(slice.origin_mm[2], 4)}},
        {"times_s", times},
        {"labels", images},
        {"channel_times_s", channel_times},
        {"channels", channels},
        {"structures", plane_structures(slice)}});
  }
  return Json{{"lung_labels", lung_labels}, {"planes", planes}};
}

// The points' positions per frame as three columns (LPS mm): the numbers trajectories.csv prints.
Json tracks_json(const std::vector<double>& times_s, const std::vector<PointTrack>& tracks) {
  Json points = Json::array();
  for (const PointTrack& track : tracks) {
    Json axes = Json::array({Json::array(), Json::array(), Json::array()});
    for (const auto& x : track.position_mm)
      for (std::size_t a = 0; a < 3; ++a) axes[a].push_back(x[a]);
    points.push_back(Json{{"name", track.name},
                          {"moves_with", track.moves_with},
                          {"rest_mm", track.rest_mm},
                          {"x_mm", axes[0]},
                          {"y_mm", axes[1]},
                          {"z_mm", axes[2]}});
  }
  Json times = Json::array();
  for (const double t : times_s) times.push_back(rounded(t, 6));
  return Json{{"times_s", times}, {"points", points}};
}

Json optional_mm(const std::optional<std::array<double, 3>>& x) { return x ? Json(*x) : Json(); }

// structures.csv and structures-summary.csv as the page lists them.
Json structures_json(const std::vector<StructureFacts>& structures) {
  Json out = Json::array();
  for (const StructureFacts& s : structures) {
    Json rows = Json::array();
    for (const StructureFacts::Row& row : s.rows)
      rows.push_back(Json{{"tag", row.tag},
                          {"time_s", row.time_s ? Json(rounded(*row.time_s, 6)) : Json()},
                          {"volume_mL", row.volume_ml},
                          {"centroid_mm", optional_mm(row.centroid_mm)},
                          {"weight", row.weight}});
    out.push_back(Json{{"name", s.name},
                       {"rows", rows},
                       {"itv_mL", s.itv_ml ? Json(*s.itv_ml) : Json()},
                       {"midventilation", s.midventilation.empty() ? Json() : Json(s.midventilation)},
                       {"midventilation_mm", optional_mm(s.midventilation_mm)},
                       {"mean_mm", optional_mm(s.mean_mm)}});
  }
  return out;
}

Json voxel_points_json(const std::vector<VoxelPointFigures>& points) {
  Json out = Json::array();
  for (const VoxelPointFigures& p : points) {
    out.push_back(Json{{"tag", p.tag},
                       {"time_s", p.time_s ? Json(rounded(*p.time_s, 6)) : Json()},
                       {"volume_error_percent", rounded(p.volume_error_percent, 4)},
                       {"min_jacobian", rounded(p.min_jacobian, 4)},
                       {"folded_tets", p.folded_tets}});
  }
  return out;
}

// Fills `@NAME@` placeholders of the template in one pass over the template only (what is
// substituted, three.js among it, is never scanned). Every placeholder must be known.
std::string fill(std::string_view page, const std::map<std::string, std::string_view>& values) {
  std::string out;
  std::size_t total = page.size();
  for (const auto& [name, value] : values) total += value.size();
  out.reserve(total);
  std::size_t i = 0;
  while (i < page.size()) {
    const std::size_t at = page.find('@', i);
    if (at == std::string_view::npos) break;
    std::size_t end = at + 1;
    auto name_char = [](char c) { return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_'; };
    while (end < page.size() && name_char(page[end])) ++end;
    if (end < page.size() && page[end] == '@' && end > at + 1) {
      const auto found = values.find(std::string(page.substr(at + 1, end - at - 1)));
      if (found == values.end()) {
        throw Error(ExitCode::failure,
                    "report template: unknown placeholder " + std::string(page.substr(at, end - at + 1)));
      }
      out.append(page.substr(i, at - i));
      out.append(found->second);
      i = end + 1;
    } else {
      out.append(page.substr(i, at + 1 - i));
      i = at + 1;
    }
  }
  out.append(page.substr(i));
  return out;
}

}  // namespace

std::size_t report_stride(std::size_t samples, std::size_t max_samples) {
  if (max_samples < 2 || samples <= max_samples) return 1;
  return (samples + max_samples - 2) / (max_samples - 1);  // ceil(samples / (max - 1)): room for the last
}

std::string report_html(const ReportInput& input) {
  if (input.physiology == nullptr || input.physiology->series.size() == 0) {
    throw ValueError("report: no physiology series to plot");
  }
  const auto& assets = detail::report_assets();
  const std::size_t stride = report_stride(input.physiology->series.size());
  Json data;
  data["name"] = input.scenario_name;
  data["description"] = input.description;
  data["generator"] = "pneuma " PNEUMA_VERSION;
  data["duration_s"] = input.duration_s;
  data["frame_rate_hz"] = input.frame_rate_hz;
  data["frame_count"] = input.frame_count;
  Json facts = Json::array();
  for (const auto& [label, value] : input.facts) facts.push_back(Json::array({label, value}));
  data["facts"] = facts;
  add_series(data, *input.physiology, stride);
  if (input.lung_names.empty()) {
    data["motion"] = motion_json(input.motion);
  } else {
    // Two lungs: one table, each row a lung's region (report.js adds a `lung` column).
    Json regions = Json::array();
    Json dome = Json::object();
    std::size_t breaths = 0;
    for (std::size_t i = 0; i < input.lung_names.size(); ++i) {
      std::vector<BreathMotion> lung;
      for (const BreathMotion& b : input.motion) {
        if (b.lung == i) lung.push_back(b);
      }
      Json one = motion_json(lung);
      breaths = std::max(breaths, lung.size());
      dome[input.lung_names[i]] = one["dome_top_caudal_mm"];
      for (Json& r : one["regions"]) {
        r["lung"] = input.lung_names[i];
        regions.push_back(std::move(r));
      }
    }
    data["motion"] = Json{{"breaths", breaths}, {"dome_top_caudal_mm_by_lung", dome}, {"regions", regions}};
  }

  if (input.bins) data["bins"] = bins_json(*input.bins);
  if (!input.slices.empty()) data["slices"] = slices_json(input.slices, input.lung_labels);
  if (!input.voxel_points.empty()) data["voxel_points"] = voxel_points_json(input.voxel_points);
  if (!input.structures.empty()) data["structures"] = structures_json(input.structures);
  if (!input.tracks.empty()) data["trajectories"] = tracks_json(input.track_times_s, input.tracks);

  const std::string json = script_json(data);
  const std::string glb = base64(input.glb);
  const std::string title = escape_markup(input.scenario_name);
  const std::string generator = "pneuma " PNEUMA_VERSION;
  return fill(assets.page, {
                               {"TITLE", title},
                               {"GENERATOR", generator},
                               {"DATA_JSON", json},
                               {"GLB_BASE64", glb},
                               {"THREE_JS", inline_script("three.min.js", assets.three)},
                               {"GLTF_LOADER_JS", inline_script("GLTFLoader.js", assets.gltf_loader)},
                               {"ORBIT_CONTROLS_JS", inline_script("OrbitControls.js", assets.orbit_controls)},
                               {"REPORT_JS", inline_script("report.js", assets.script)},
                           });
}

void write_report(const std::filesystem::path& path, const ReportInput& input) {
  const std::string page = report_html(input);
  write_stream_atomically(
      path, true, [&](std::ostream& out) { out.write(page.data(), static_cast<std::streamsize>(page.size())); });
}

}  // namespace pneuma::outputs
