#include "pneuma/outputs/motion_csv.h"

#include <fmt/format.h>

#include "pneuma/core/atomic_file.h"

namespace pneuma::outputs {

std::vector<std::string> motion_lung_names(const model::Model& model) {
  std::vector<std::string> names;
  if (model.two_lungs()) {
    for (const model::LungModel& lung : model.lungs) names.emplace_back(scenario::lung_name(lung.side));
  }
  return names;
}

void write_motion_csv(const std::filesystem::path& path, const std::vector<BreathMotion>& breaths,
                      const std::vector<std::string>& lung_names) {
  write_stream_atomically(path, false, [&](std::ostream& out) {
    if (!lung_names.empty()) out << "lung,";
    out << "breath,start_s,region,area_cm2,caudal_mean_mm,caudal_max_mm,anterior_mean_mm,anterior_max_mm,"
           "lateral_mean_mm,lateral_max_mm,magnitude_mean_mm,magnitude_max_mm,volume_share_pct,"
           "breath_volume_change_mL,dome_top_caudal_mm\n";
    for (const BreathMotion& b : breaths) {
      for (mesh::Region region : mesh::kRegions) {
        const mesh::RegionMotion& r = b.summary.region[static_cast<std::size_t>(region)];
        if (!lung_names.empty()) out << lung_names.at(b.lung) << ',';
        out << fmt::format(
            "{},{:.3f},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.3f},{:.4f},{:.4f}\n",
            b.breath, b.start_s, mesh::region_name(region), r.area_m2 * 1e4, r.caudal_mean_m * 1e3,
            r.caudal_max_m * 1e3, r.anterior_mean_m * 1e3, r.anterior_max_m * 1e3, r.lateral_mean_m * 1e3,
            r.lateral_max_m * 1e3, r.magnitude_mean_m * 1e3, r.magnitude_max_m * 1e3, r.volume_share * 100.0,
            b.summary.volume_change_m3 * 1e6, b.summary.dome_top_caudal_m * 1e3);
      }
    }
  });
}

std::vector<std::pair<std::string, std::string>> motion_facts(const std::vector<BreathMotion>& all,
                                                              const std::vector<std::string>& lung_names) {
  if (!lung_names.empty()) {
    std::vector<std::pair<std::string, std::string>> facts;
    for (std::size_t i = 0; i < lung_names.size(); ++i) {
      std::vector<BreathMotion> lung;
      for (const BreathMotion& b : all) {
        if (b.lung == i) lung.push_back(b);
      }
      for (auto& [key, value] : motion_facts(lung))
        facts.emplace_back("motion." + lung_names[i] + key.substr(6), value);
    }
    return facts;
  }
  const std::vector<BreathMotion>& breaths = all;
  std::vector<std::pair<std::string, std::string>> facts;
  if (breaths.empty()) return facts;
  const double n = static_cast<double>(breaths.size());
  auto mean = [&](auto value) {
    double sum = 0.0;
    for (const BreathMotion& b : breaths) sum += value(b);
    return sum / n;
  };
  facts.emplace_back("motion.breaths", std::to_string(breaths.size()));
  facts.emplace_back(
      "motion.dome_top_caudal_mm",
      fmt::format("{:.3f}", mean([](const BreathMotion& b) { return b.summary.dome_top_caudal_m * 1e3; })));
  for (mesh::Region region : mesh::kRegions) {
    const auto i = static_cast<std::size_t>(region);
    const std::string prefix = fmt::format("motion.{}.", mesh::region_name(region));
    facts.emplace_back(
        prefix + "caudal_mean_mm",
        fmt::format("{:.3f}", mean([&](const BreathMotion& b) { return b.summary.region[i].caudal_mean_m * 1e3; })));
    facts.emplace_back(
        prefix + "magnitude_mean_mm",
        fmt::format("{:.3f}", mean([&](const BreathMotion& b) { return b.summary.region[i].magnitude_mean_m * 1e3; })));
    facts.emplace_back(
        prefix + "magnitude_max_mm",
        fmt::format("{:.3f}", mean([&](const BreathMotion& b) { return b.summary.region[i].magnitude_max_m * 1e3; })));
    facts.emplace_back(
        prefix + "volume_share_pct",
        fmt::format("{:.2f}", mean([&](const BreathMotion& b) { return b.summary.region[i].volume_share * 100.0; })));
  }
  return facts;
}

namespace {

class MotionCsv final : public Output {
 public:
  explicit MotionCsv(std::filesystem::path file) : file_(std::move(file)) {}
  std::string name() const override { return "motion_csv"; }
  std::vector<std::filesystem::path> finish(const model::Model& model, const RunRecord& run) override {
    const std::vector<std::string> lungs = motion_lung_names(model);
    write_motion_csv(file_, *run.motion, lungs);
    facts_ = motion_facts(*run.motion, lungs);
    return {file_};
  }
  std::vector<std::pair<std::string, std::string>> facts() const override { return facts_; }

 private:
  std::filesystem::path file_;
  std::vector<std::pair<std::string, std::string>> facts_;
};

}  // namespace

OutputPlugin motion_csv_output() {
  return {{"motion_csv", true, no_settings},
          {.breath_motion = true},
          [](const std::any&, const std::filesystem::path& out) {
            return std::make_unique<MotionCsv>(out / "motion.csv");
          }};
}

}  // namespace pneuma::outputs
