#include "pneuma/outputs/physiology_csv.h"

#include <fmt/format.h>
#include <fmt/os.h>

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "pneuma/core/atomic_file.h"
#include "pneuma/outputs/ventilator_facts.h"
#include "pneuma/physiology/columns.h"

namespace pneuma::outputs {
namespace {

// A cell as physiology.csv has always written it; nothing: an empty cell.
std::string cell(physiology::CellFormat format, std::optional<double> value) {
  if (!value) return {};
  switch (format) {
    case physiology::CellFormat::fixed6: return fmt::format("{:.6f}", *value);
    case physiology::CellFormat::whole: return fmt::format("{}", static_cast<long long>(*value));
    default: return fmt::format("{:.9g}", *value);
  }
}

}  // namespace

void write_time_series_csv(const std::filesystem::path& path, const physiology::SimulationResult& result) {
  const auto& s = result.series;
  const std::vector<physiology::SeriesColumn> columns = physiology::series_columns(result);
  write_stream_atomically(path, false, [&](std::ostream& out) {
    for (std::size_t c = 0; c < columns.size(); ++c) out << (c ? "," : "") << columns[c].name;
    out << '\n';
    std::string line;
    for (std::size_t k = 0; k < s.size(); ++k) {
      line.clear();
      for (std::size_t c = 0; c < columns.size(); ++c) {
        if (c) line += ',';
        line += cell(columns[c].format, columns[c].at(s, k));
      }
      line += '\n';
      out << line;
    }
  });
}

void write_breaths_csv(const std::filesystem::path& path, const physiology::SimulationResult& result) {
  const std::span<const physiology::BreathColumn> columns = physiology::breath_columns();
  write_stream_atomically(path, false, [&](std::ostream& out) {
    for (std::size_t c = 0; c < columns.size(); ++c) out << (c ? "," : "") << columns[c].name;
    out << '\n';
    std::string line;
    for (std::size_t i = 0; i < result.breaths.size(); ++i) {
      line.clear();
      for (std::size_t c = 0; c < columns.size(); ++c) {
        if (c) line += ',';
        const physiology::BreathColumn& column = columns[c];
        if (column.format == physiology::CellFormat::text) line += column.text(result.breaths[i]);
        else line += cell(column.format, column.number(result.breaths[i], i));
      }
      line += '\n';
      out << line;
    }
  });
}

namespace {

class PhysiologyCsv final : public Output {
 public:
  explicit PhysiologyCsv(std::filesystem::path dir) : dir_(std::move(dir)) {}
  std::string name() const override { return "physiology_csv"; }
  std::vector<std::filesystem::path> finish(const model::Model&, const RunRecord& run) override {
    write_time_series_csv(dir_ / "physiology.csv", *run.physiology);
    write_breaths_csv(dir_ / "physiology-breaths.csv", *run.physiology);
    // The ventilator's settings and a summary of the breaths the CSV lists, for the manifest.
    if (run.scenario) facts_ = ventilator_facts(run.scenario->physiology.protocol, *run.physiology);
    return {dir_ / "physiology.csv", dir_ / "physiology-breaths.csv"};
  }
  std::vector<std::pair<std::string, std::string>> facts() const override { return facts_; }

 private:
  std::filesystem::path dir_;
  std::vector<std::pair<std::string, std::string>> facts_;
};

}  // namespace

OutputPlugin physiology_csv_output() {
  return {{"physiology_csv", true, no_settings},
          {.physiology = true},
          [](const std::any&, const std::filesystem::path& out) { return std::make_unique<PhysiologyCsv>(out); }};
}

}  // namespace pneuma::outputs
