// Trace readers: CSV with a header (pneuma's own physiology.csv, a spirometer export, a Pulse
// Physiology Engine results file) and Varian RPM .vxp 1.5 / 1.6.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <string_view>

#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"
#include "pneuma/core/text.h"
#include "pneuma/core/units.h"
#include "pneuma/physiology/trace.h"

namespace pneuma::physiology {
namespace {

// Absolute lung volumes stay below about 8 L (a large adult's total lung capacity); a column
// with more is not a lung volume (a wrong unit, a wrong column).
constexpr double kMaxAbsoluteVolumeM3 = 10e-3;

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  if (s.size() >= 2 && s.front() == '"' && s.back() == '"') s = s.substr(1, s.size() - 2);
  return s;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::vector<std::string_view> split(std::string_view line, char separator) {
  std::vector<std::string_view> out;
  std::size_t begin = 0;
  for (;;) {
    const std::size_t comma = line.find(separator, begin);
    out.push_back(trim(line.substr(begin, comma == std::string_view::npos ? std::string_view::npos : comma - begin)));
    if (comma == std::string_view::npos) return out;
    begin = comma + 1;
  }
}

// The file's lines (without their ends), numbered from 1.
std::vector<std::string_view> lines_of(std::string_view text) {
  std::vector<std::string_view> lines;
  std::size_t begin = 0;
  while (begin < text.size()) {
    std::size_t end = text.find('\n', begin);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(begin, end - begin);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    lines.push_back(line);
    begin = end + 1;
  }
  return lines;
}

std::string where(const std::filesystem::path& file, std::size_t line) {
  std::string out = file.string();
  return out.append(":").append(std::to_string(line)).append(": ");
}

std::string number_text(double x) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%g", x);
  return buffer;
}

// A finite number taking the whole cell, or nullopt.
std::optional<double> number(std::string_view cell) {
  if (cell.empty()) return std::nullopt;
  if (cell.front() == '+') cell.remove_prefix(1);
  double value = 0.0;
  const auto [end, ec] = std::from_chars(cell.data(), cell.data() + cell.size(), value);
  if (ec != std::errc() || end != cell.data() + cell.size() || !std::isfinite(value)) return std::nullopt;
  return value;
}

// A header cell split into its name and unit: "volume_mL", "volume (mL)", "Time(s)",
// "flow [L/s]", "flow_L_per_s"; the unit is "" when there is none.
struct Header {
  std::string text, name, unit;
};

// SI value of one `unit` when it is of `kind`.
std::optional<double> unit_factor(const std::string& unit, const units::Kind& kind) {
  if (unit.empty()) return std::nullopt;
  try {
    return units::parse("1 " + unit, kind);
  } catch (const units::UnitError&) {
    return std::nullopt;
  }
}

bool is_unit(const std::string& unit) {
  for (const units::Kind* k :
       {&units::kind::duration, &units::kind::volume, &units::kind::flow, &units::kind::length}) {
    if (unit_factor(unit, *k)) return true;
  }
  return false;
}

std::string underscore_unit(std::string_view text) {
  std::string unit;
  for (std::size_t k = 0; k < text.size(); ++k) {
    if (text.substr(k, 5) == "_per_") {
      unit.push_back('/');
      k += 4;
    } else {
      unit.push_back(text[k] == '_' ? '*' : text[k]);
    }
  }
  return unit;
}

Header parse_header(std::string_view cell) {
  Header h{std::string(cell), std::string(cell), ""};
  for (const auto& [open, close] : {std::pair{'(', ')'}, std::pair{'[', ']'}}) {
    if (!cell.empty() && cell.back() == close) {
      if (const auto at = cell.rfind(open); at != std::string_view::npos) {
        h.name = std::string(trim(cell.substr(0, at)));
        h.unit = std::string(trim(cell.substr(at + 1, cell.size() - at - 2)));
        return h;
      }
    }
  }
  // "volume_mL", "flow_L_per_s": the shortest name whose suffix is a unit.
  for (std::size_t at = cell.find('_'); at != std::string_view::npos; at = cell.find('_', at + 1)) {
    const std::string unit = underscore_unit(cell.substr(at + 1));
    if (is_unit(unit)) {
      h.name = std::string(cell.substr(0, at));
      h.unit = unit;
      return h;
    }
  }
  return h;
}

std::optional<TraceSignal> signal_of_name(const std::string& name) {
  const std::string n = lower(name);
  if (n == "volume" || n == "lung_volume" || n == "totallungvolume") return TraceSignal::volume;
  if (n == "flow" || n == "airflow") return TraceSignal::flow;
  if (n == "amplitude" || n == "signal" || n == "displacement") return TraceSignal::amplitude;
  return std::nullopt;
}

std::vector<std::string> header_texts(const std::vector<Header>& headers) {
  std::vector<std::string> out;
  out.reserve(headers.size());
  for (const Header& h : headers) out.push_back("'" + h.text + "'");
  return out;
}

RawTrace read_csv(const std::filesystem::path& file, std::string_view text, const TraceOptions& options) {
  const std::vector<std::string_view> lines = lines_of(text);
  std::size_t header_line = 0;
  while (header_line < lines.size() && (trim(lines[header_line]).empty() || trim(lines[header_line]).front() == '#'))
    ++header_line;
  if (header_line == lines.size())
    throw InputError(file.string() + ": empty trace (expected a header line such as 'time_s,volume_mL', then samples)");
  std::vector<Header> headers;
  for (std::string_view cell : split(lines[header_line], ',')) headers.push_back(parse_header(cell));
  const std::string at_header = where(file, header_line + 1);

  // The time column.
  std::size_t time_column = headers.size();
  for (std::size_t c = 0; c < headers.size(); ++c) {
    const std::string n = lower(headers[c].name);
    if (n == "time" || n == "t") {
      time_column = c;
      break;
    }
  }
  if (time_column == headers.size())
    throw InputError(at_header + "no time column (expected a header such as 'time_s' or 'Time(s)'; columns: " +
                     join_names(header_texts(headers)) + ")");
  const auto seconds_per_unit = unit_factor(headers[time_column].unit, units::kind::duration);
  if (!seconds_per_unit)
    throw InputError(at_header + "column '" + headers[time_column].text +
                     "': expected a time with its unit, such as 'time_s' or 'time (s)'");

  // The signal column: named, else the first whose name says what it is (of the kind asked for).
  std::size_t column = headers.size();
  if (!options.column.empty()) {
    for (std::size_t c = 0; c < headers.size(); ++c) {
      if (headers[c].text == options.column || headers[c].name == options.column) column = c;
    }
    if (column == headers.size())
      throw InputError(at_header + "no column '" + options.column + "' (columns: " + join_names(header_texts(headers)) +
                       ")");
  } else {
    for (std::size_t c = 0; c < headers.size() && column == headers.size(); ++c) {
      const auto s = signal_of_name(headers[c].name);
      if (s && (!options.signal || *s == *options.signal)) column = c;
    }
    if (column == headers.size()) {
      const std::string what = options.signal ? std::string("no ") + signal_name(*options.signal) + " column"
                                              : std::string("no volume, flow or amplitude column");
      throw InputError(at_header + what + " (columns: " + join_names(header_texts(headers)) +
                       "; name one with the driver's 'column')");
    }
  }
  const Header& h = headers[column];
  RawTrace raw;
  raw.file = file;
  raw.column = h.text;
  double factor = 1.0;
  if (auto f = unit_factor(h.unit, units::kind::volume)) {
    raw.signal = TraceSignal::volume;
    factor = *f;
  } else if (auto q = unit_factor(h.unit, units::kind::flow)) {
    raw.signal = TraceSignal::flow;
    factor = *q;
  } else if (h.unit.empty() || unit_factor(h.unit, units::kind::length)) {
    const auto named = signal_of_name(h.name);
    if (named == TraceSignal::volume || named == TraceSignal::flow || options.signal == TraceSignal::volume ||
        options.signal == TraceSignal::flow) {
      const bool volume = named == TraceSignal::volume || options.signal == TraceSignal::volume;
      throw InputError(at_header + "column '" + h.text + "': expected a " + (volume ? "volume" : "flow") +
                       " with its unit, such as " +
                       (volume ? "'volume_mL' or 'volume (mL)'" : "'flow_L_per_s' or 'flow (L/s)'"));
    }
    raw.signal = TraceSignal::amplitude;
    raw.amplitude_unit = h.unit;
  } else {
    throw InputError(at_header + "column '" + h.text + "': unit '" + h.unit +
                     "' is not a volume, a flow or a length (expected e.g. 'volume_mL', 'flow (L/s)', 'amplitude_cm')");
  }
  if (options.signal && *options.signal != raw.signal)
    throw InputError(at_header + "column '" + h.text + "' holds a " + signal_name(raw.signal) + ", not a " +
                     signal_name(*options.signal));

  for (std::size_t l = header_line + 1; l < lines.size(); ++l) {
    const std::string_view line = lines[l];
    if (trim(line).empty() || trim(line).front() == '#') continue;
    const std::vector<std::string_view> cells = split(line, ',');
    const std::string at = where(file, l + 1);
    if (cells.size() <= std::max(time_column, column))
      throw InputError(at + "expected " + std::to_string(headers.size()) + " columns, got " +
                       std::to_string(cells.size()));
    const auto t = number(cells[time_column]);
    if (!t)
      throw InputError(at + "column '" + headers[time_column].text + "': expected a number, got " +
                       quote_input(cells[time_column]));
    const auto v = number(cells[column]);
    if (!v) throw InputError(at + "column '" + h.text + "': expected a number, got " + quote_input(cells[column]));
    const double time = *t * *seconds_per_unit;
    if (!raw.time_s.empty() && !(time > raw.time_s.back()))
      throw InputError(at + "time " + number_text(*t) + " is not after the previous sample's " +
                       number_text(raw.time_s.back() / *seconds_per_unit) + " (times must increase)");
    const double value = *v * factor;
    if (raw.signal == TraceSignal::volume && value < 0.0)
      throw InputError(at + "volume " + number_text(*v) + " " + h.unit + " is below zero (expected a lung volume)");
    if (raw.signal == TraceSignal::volume && value > kMaxAbsoluteVolumeM3)
      throw InputError(at + "volume " + number_text(*v) + " " + h.unit +
                       " is far beyond a lung's range (at most 10 L; is the unit right?)");
    raw.time_s.push_back(time);
    raw.value.push_back(value);
    raw.valid.push_back(true);
    raw.line.push_back(l + 1);
  }
  if (raw.time_s.empty())
    throw InputError(at_header + "no samples after the header (expected rows such as '0.0,2400')");
  return raw;
}

// Where an RPM row keeps its amplitude, timestamp (ms) and validflag (kNoField: none, all valid).
constexpr std::size_t kNoField = static_cast<std::size_t>(-1);
struct RpmFields {
  std::size_t amplitude, timestamp, validflag;
};

// One RPM row into `raw`: its amplitude times `cm_per_value`, its time from the first row's
// timestamp (`first_ms`, set by the first row). Throws InputError at `at` for a field that is not
// a number or a time that does not increase.
void add_rpm_sample(RawTrace& raw, const std::vector<std::string_view>& cells, const RpmFields& f, double cm_per_value,
                    const std::string& at, std::size_t line, double& first_ms) {
  const auto a = number(cells[f.amplitude]);
  if (!a) throw InputError(at + "amplitude: expected a number, got " + quote_input(cells[f.amplitude]));
  const auto ms = number(cells[f.timestamp]);
  if (!ms) throw InputError(at + "timestamp: expected a number (ms), got " + quote_input(cells[f.timestamp]));
  bool valid = true;
  if (f.validflag != kNoField) {
    const auto flag = number(cells[f.validflag]);
    if (!flag) throw InputError(at + "validflag: expected a number, got " + quote_input(cells[f.validflag]));
    valid = *flag >= 0.0;
  }
  if (raw.time_s.empty()) first_ms = *ms;
  const double time = (*ms - first_ms) * 1e-3;
  if (!raw.time_s.empty() && !(time > raw.time_s.back()))
    throw InputError(at + "timestamp " + number_text(*ms) + " ms is not after the previous sample's " +
                     number_text(raw.time_s.back() * 1e3 + first_ms) + " ms (times must increase)");
  raw.time_s.push_back(time);
  raw.value.push_back(*a * cm_per_value);
  raw.valid.push_back(valid);
  raw.line.push_back(line);
}

// Varian RPM .vxp (versions 1.5 and 1.6), as plastimatch's readrpm.m (1.5, 2009) reads it: a
// [Header] of key=value lines (Data_layout names the columns, Samples_per_second, Scale_factor),
// then [Data] rows "amplitude,phase,timestamp,validflag,ttlin,mark,ttlout" with the amplitude in
// cm as value * Scale_factor / 10 (so the usual Scale_factor=10 means values in cm), the
// timestamp in ms, validflag < 0 for a sample the system marked invalid, and marks Z / P at
// phase zero and pi.
RawTrace read_vxp(const std::filesystem::path& file, std::string_view text) {
  const std::vector<std::string_view> lines = lines_of(text);
  std::size_t l = 0;
  while (l < lines.size() && trim(lines[l]).empty()) ++l;
  if (l == lines.size()) throw InputError(file.string() + ": empty RPM file (expected '[Header]', then '[Data]')");
  if (trim(lines[l]) != "[Header]")
    throw InputError(where(file, l + 1) + "expected '[Header]' (a Varian RPM .vxp file), got " +
                     quote_input(trim(lines[l])));
  const std::size_t header_line = l + 1;
  std::map<std::string, std::pair<std::string, std::size_t>> fields;
  for (++l; l < lines.size() && trim(lines[l]) != "[Data]"; ++l) {
    const std::string_view line = trim(lines[l]);
    if (line.empty()) continue;
    const auto eq = line.find('=');
    if (eq == std::string_view::npos)
      throw InputError(where(file, l + 1) + "expected 'key=value' in the RPM header, got " + quote_input(line));
    fields[std::string(trim(line.substr(0, eq)))] = {std::string(trim(line.substr(eq + 1))), l + 1};
  }
  if (l == lines.size()) throw InputError(where(file, header_line) + "no '[Data]' section after the RPM header");
  const std::size_t data_line = l + 1;
  auto field = [&](const char* key) -> const std::pair<std::string, std::size_t>& {
    auto it = fields.find(key);
    if (it == fields.end())
      throw InputError(where(file, header_line) + "the RPM header has no '" + key +
                       "' (needed: Version, Data_layout, Samples_per_second, Scale_factor)");
    return it->second;
  };
  const auto& version = field("Version");
  if (version.first != "1.5" && version.first != "1.6")
    throw InputError(where(file, version.second) + "RPM version '" + version.first + "' (expected 1.5 or 1.6)");
  const auto& layout = field("Data_layout");
  const auto& rate = field("Samples_per_second");
  const auto& scale = field("Scale_factor");
  const auto samples_per_second = number(rate.first);
  if (!samples_per_second || !(*samples_per_second > 0.0))
    throw InputError(where(file, rate.second) + "Samples_per_second: expected a positive number, got " +
                     quote_input(rate.first));
  const auto scale_factor = number(scale.first);
  if (!scale_factor || !(*scale_factor > 0.0))
    throw InputError(where(file, scale.second) + "Scale_factor: expected a positive number, got " +
                     quote_input(scale.first));
  const std::vector<std::string_view> columns = split(layout.first, ',');
  auto column_of = [&](std::string_view name) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      if (lower(columns[c]) == name) return c;
    }
    return columns.size();
  };
  const std::size_t amplitude = column_of("amplitude"), timestamp = column_of("timestamp"),
                    validflag = column_of("validflag");
  if (amplitude == columns.size() || timestamp == columns.size())
    throw InputError(where(file, layout.second) + "Data_layout has no 'amplitude' or no 'timestamp' column (got '" +
                     layout.first + "')");

  RawTrace raw;
  raw.file = file;
  raw.signal = TraceSignal::amplitude;
  raw.column = "amplitude";
  raw.amplitude_unit = "cm";
  raw.nominal_interval_s = 1.0 / *samples_per_second;
  double first_ms = 0.0;
  for (l = data_line; l < lines.size(); ++l) {
    if (trim(lines[l]).empty()) continue;
    const std::vector<std::string_view> cells = split(lines[l], ',');
    const std::string at = where(file, l + 1);
    if (cells.size() < columns.size())
      throw InputError(at + "expected " + std::to_string(columns.size()) + " fields (" + layout.first + "), got " +
                       std::to_string(cells.size()));
    add_rpm_sample(raw, cells, {amplitude, timestamp, validflag == columns.size() ? kNoField : validflag},
                   *scale_factor / 10.0, at, l + 1, first_ms);
  }
  if (raw.time_s.empty()) throw InputError(where(file, data_line) + "no samples after '[Data]'");
  return raw;
}

// The older Varian RPM .dat (versions 1.4 and 1.7), as plastimatch's readrpm.m reads it (the
// only public description): line 1 starts with "CRC", line 2 is "VERSION = 1.4", lines 3-5 the
// reference position, the gating type (#TRUE# phase, #FALSE# amplitude) and the gating window,
// lines 6-10 more settings; from line 11 one sample a row, comma-separated: 1.4
// "amplitude,phase,timestamp,validflag,video,ttlin,beam", 1.7 with two more fields after the
// amplitude ("amplitude,_,_,phase,timestamp,validflag,video,ttlin,beam"). The amplitude is in cm
// (readrpm assumes so too: the header has no scale), the timestamp in ms. There is no sampling
// rate in the header: gaps are judged against the median interval.
RawTrace read_dat(const std::filesystem::path& file, std::string_view text) {
  constexpr std::size_t kHeaderLines = 10;
  const std::vector<std::string_view> lines = lines_of(text);
  if (lines.empty() || trim(lines[0]).substr(0, 3) != "CRC")
    throw InputError(where(file, 1) + "expected 'CRC' on the first line (a Varian RPM .dat file)");
  const std::string_view version_line = lines.size() > 1 ? trim(lines[1]) : std::string_view();
  const auto eq = version_line.find('=');
  std::string version;  // "VERSION = 1.4," (readrpm reads it as 'VERSION = %s,')
  if (eq != std::string_view::npos && lower(trim(version_line.substr(0, eq))) == "version") {
    const std::string_view value = trim(version_line.substr(eq + 1));
    version = std::string(trim(value.substr(0, value.find(','))));
  }
  if (version != "1.4" && version != "1.7")
    throw InputError(where(file, 2) + "RPM .dat version '" + std::string(version_line) +
                     "' (expected 'VERSION = 1.4' or 'VERSION = 1.7')");
  if (lines.size() <= kHeaderLines)
    throw InputError(where(file, lines.size()) + "no samples after the RPM .dat header (10 lines)");
  // Field positions: amplitude, phase, timestamp, validflag, and how many a row has at least.
  const bool v17 = version == "1.7";
  const std::size_t amplitude = 0, timestamp = v17 ? 4 : 2, validflag = v17 ? 5 : 3, fields = v17 ? 9 : 7;
  const char* layout = v17 ? "amplitude,_,_,phase,timestamp,validflag,video,ttlin,beam"
                           : "amplitude,phase,timestamp,validflag,video,ttlin,beam";

  RawTrace raw;
  raw.file = file;
  raw.signal = TraceSignal::amplitude;
  raw.column = "amplitude";
  raw.amplitude_unit = "cm";
  double first_ms = 0.0;
  for (std::size_t l = kHeaderLines; l < lines.size(); ++l) {
    if (trim(lines[l]).empty()) continue;
    std::vector<std::string_view> cells = split(lines[l], ',');
    while (!cells.empty() && trim(cells.back()).empty()) cells.pop_back();  // a trailing comma
    const std::string at = where(file, l + 1);
    if (cells.size() < fields)
      throw InputError(at + "expected " + std::to_string(fields) + " fields (" + layout + "), got " +
                       std::to_string(cells.size()));
    add_rpm_sample(raw, cells, {amplitude, timestamp, validflag}, 1.0, at, l + 1, first_ms);
  }
  if (raw.time_s.empty()) throw InputError(where(file, kHeaderLines + 1) + "no samples after the RPM .dat header");
  return raw;
}

}  // namespace

const char* signal_name(TraceSignal signal) {
  switch (signal) {
    case TraceSignal::volume: return "volume";
    case TraceSignal::flow: return "flow";
    case TraceSignal::amplitude: return "amplitude";
  }
  return "?";
}

RawTrace read_trace_file(const std::filesystem::path& file, const TraceOptions& options) {
  const std::string bytes = read_file_bytes(file);
  const std::string_view text = without_bom(bytes);
  if (options.format == TraceFormat::rpm) {
    // Both RPM formats: the .dat's first line starts with "CRC", the .vxp's is "[Header]".
    const std::vector<std::string_view> lines = lines_of(text);
    const bool dat = !lines.empty() && trim(lines.front()).substr(0, 3) == "CRC";
    return dat ? read_dat(file, text) : read_vxp(file, text);
  }
  return read_csv(file, text, options);
}

}  // namespace pneuma::physiology
