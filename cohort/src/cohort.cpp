#include "pneuma/cohort/cohort.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdint>
#include <map>

#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"
#include "pneuma/core/text.h"
#include "pneuma/field/field_solver.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/scenario/config.h"

namespace pneuma::cohort {
namespace {

namespace kind = units::kind;

// Ids name folders and Snakemake wildcards: no slashes, spaces or shell characters.
bool valid_id(const std::string& id) {
  return !id.empty() && id.front() != '.' && std::all_of(id.begin(), id.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == '-';
  });
}

// Snakemake 7.21 stops the whole workflow (PeriodicWildcardError, before any job) for a wildcard
// value that ends in one piece repeated 20 times or more ("aaaaaaaaaaaaaaaaaaaa", "x-ab-ab-...-ab"):
// its guard against a rule feeding itself (snakemake/io.py, PeriodicityDetector).
constexpr std::size_t kSnakemakeRepeats = 20;
bool ends_in_repeats(const std::string& id) {
  for (std::size_t period = 1; period * kSnakemakeRepeats <= id.size(); ++period) {
    bool periodic = true;
    for (std::size_t i = id.size() - period * kSnakemakeRepeats; i + period < id.size() && periodic; ++i)
      periodic = id[i] == id[i + period];
    if (periodic) return true;
  }
  return false;
}

void check_id(const scenario::Node& node, const std::string& key, const char* what) {
  if (!valid_id(key))
    node.fail_at(
        key, fmt::format("expected a {} id of letters, digits, '.', '_' and '-' (a folder name), got '{}'", what, key));
  if (ends_in_repeats(key))
    node.fail_at(key, fmt::format("expected a {} id that does not end in one piece repeated {} times or more "
                                  "(Snakemake stops the cohort for it), got {}",
                                  what, kSnakemakeRepeats, quote_input(key)));
}

// The mesh keys that describe the surface: a subject's `mesh:` replaces these of the scenario's
// (which keeps `breath` / `reference_volume`, a property of the breathing, not of the anatomy).
constexpr const char* kSurfaceKeys[] = {"phantom", "file",   "labels", "values", "unit",
                                        "edge",    "repair", "export", "share"};

// The cache is the cohort's to set (fields/<subject>/<variant>.h5).
void refuse_cache(const scenario::Node& node, const std::string& where) {
  if (auto field = node.optional_map("field")) {
    if (field->has("cache"))
      field->fail_at("cache", "the cohort keeps each subject's field in fields/<subject>/<variant>.h5; remove '" +
                                  where + "field.cache'");
  }
}

YAML::Node parse(const std::string& text, const std::string& name) {
  try {
    return YAML::Load(std::string(without_bom(text)));
  } catch (const YAML::Exception& e) {
    throw InputError(location(name, e.mark.line, e.mark.column) + ": not valid YAML: " + e.msg);
  }
}

// A map node holding `key: value` for each present value (shared, so that their positions in
// the file they came from stay with them).
YAML::Node layer(std::initializer_list<std::pair<const char*, YAML::Node>> entries) {
  YAML::Node map(YAML::NodeType::Map);
  for (const auto& [key, value] : entries) {
    if (value && value.IsDefined() && !value.IsNull()) map.force_insert(key, value);
  }
  return map;
}

std::string dump(const YAML::Node& node) {
  if (!node || !node.IsDefined()) return "~";
  YAML::Emitter out;
  out << YAML::Flow << node;
  return out.c_str();
}

// FNV-1a, 64 bits: a stable digest (the same on every machine and build) for Snakemake params.
std::string digest(const std::string& text) {
  std::uint64_t h = 14695981039346656037ull;
  for (unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return fmt::format("{:016x}", h);
}

const ScenarioEntry& find_scenario(const Cohort& c, const std::string& id) {
  for (const auto& s : c.scenarios) {
    if (s.id == id) return s;
  }
  throw InputError(
      fmt::format("{}: scenarios: no scenario '{}' (the cohort has: {})", c.file.string(), id, join_names([&] {
                    std::vector<std::string> ids;
                    for (const auto& e : c.scenarios) ids.push_back(e.id);
                    return ids;
                  }())));
}

const Subject& find_subject(const Cohort& c, const std::string& id) {
  for (const auto& s : c.subjects) {
    if (s.id == id) return s;
  }
  std::vector<std::string> ids;
  for (const auto& s : c.subjects) ids.push_back(s.id);
  throw InputError(
      fmt::format("{}: subjects: no subject '{}' (the cohort has: {})", c.file.string(), id, join_names(ids)));
}

// What makes two scenarios' fields of one surface the same field: the tissue file and name and
// the solver options (as the field cache's key, model/field_cache.h).
std::string field_variant_key(const scenario::Scenario& s) {
  const auto& o = s.field.options;
  return fmt::format("{}|{}|{}|{:.17g}|{}|{}|{:.17g}",
                     std::filesystem::absolute(s.field.tissue_file).lexically_normal().string(), s.field.tissue.name,
                     field::solver_name(o.solver), o.tolerance, o.clique_hops, static_cast<int>(o.path_rule),
                     o.area_unit);
}

std::string variant_name(const scenario::Scenario& s) {
  std::string name = s.field.tissue_file.stem().string();
  if (!valid_id(name) || ends_in_repeats(name)) name = "field";
  return name;
}

}  // namespace

Cohort load_cohort(const std::filesystem::path& file) {
  Cohort c;
  c.file = file;
  c.text = read_file_bytes(file);
  const scenario::Node root = scenario::Node::load_string(c.text, file.string());
  c.name = root.optional_string("name").value_or(file.stem().string());
  if (root.has("edge")) c.edge_m = root.positive_quantity("edge", kind::length);
  // Read per job, over each scenario, by the scenario reader (which checks them against the
  // cohort file's lines): here only accepted.
  refuse_cache(root, "");
  root.accept("field");
  if (root.has("outputs") && !root.is_map("outputs")) root.fail_at("outputs", "expected a mapping of outputs");
  root.accept("outputs");
  if (auto r = root.optional_map("resources")) {
    c.resources.threads = static_cast<int>(r->integer("threads", 1, 1, 1024));
    c.resources.memory_mb = r->integer("memory_mb", 2048, 16, 16L << 20);
    if (r->has("runtime")) {
      const double seconds = r->positive_quantity("runtime", kind::duration);
      c.resources.runtime_min = std::max(1L, static_cast<long>(std::ceil(seconds / 60.0)));
    }
    r->finish();
  }

  const scenario::Node subjects = root.map("subjects");
  for (const std::string& id : subjects.keys()) {
    check_id(subjects, id, "subject");
    if (!subjects.is_map(id)) subjects.fail_at(id, "expected a subject: a mapping with 'mesh' (and 'field')");
    const scenario::Node subject = subjects.map(id);
    Subject s{id, {}};
    const scenario::Node mesh = subject.map("mesh");
    for (const char* key : {"labels", "file"}) {
      if (mesh.has(key)) s.inputs.push_back(std::filesystem::absolute(mesh.directory(key) / mesh.string(key)));
    }
    mesh.accept("phantom");
    for (const char* key : kSurfaceKeys) mesh.accept(key);
    mesh.accept("breath");            // checked by the scenario reader, with every other key
    mesh.accept("reference_volume");  // (breath's older name)
    refuse_cache(subject, "subjects." + id + ".");
    subject.accept("field");
    subject.finish();
    c.subjects.push_back(std::move(s));
  }
  if (c.subjects.empty()) root.fail_at("subjects", "expected at least one subject");

  const scenario::Node scenarios = root.map("scenarios");
  for (const std::string& id : scenarios.keys()) {
    check_id(scenarios, id, "scenario");
    const std::filesystem::path path = (scenarios.directory(id) / scenarios.string(id)).lexically_normal();
    if (!path_exists(path)) scenarios.fail_at(id, "no such scenario file: " + path.string());
    c.scenarios.push_back({id, path});
  }
  if (c.scenarios.empty()) root.fail_at("scenarios", "expected at least one scenario: 'id: path/to/scenario.yaml'");
  root.finish();
  return c;
}

scenario::Scenario job_scenario(const Cohort& c, const std::string& subject_id, const std::string& scenario_id,
                                const std::filesystem::path& field_file) {
  find_subject(c, subject_id);
  const ScenarioEntry& entry = find_scenario(c, scenario_id);
  const std::string cohort_name = c.file.string();
  const YAML::Node cohort = parse(c.text, cohort_name);
  const YAML::Node subject = cohort["subjects"][subject_id];

  // The scenario file without its surface keys (the subject's replace them).
  // As the cohort names it, relative to the cohort file's folder: in messages and the run's
  // manifest (the jobs read the cohort by its absolute path, so theirs is absolute).
  const std::string scenario_name = entry.file.string();
  YAML::Node scenario = parse(read_file_bytes(entry.file), scenario_name);
  if (scenario.IsMap() && scenario["mesh"] && scenario["mesh"].IsMap()) {
    YAML::Node mesh = scenario["mesh"];
    for (const char* key : kSurfaceKeys) mesh.remove(key);
  }
  // Layers, first wins (scenario::Node::with_fallback merges mappings key by key, and each value
  // is reported with the file and line it came from): the cache, the subject, the cohort, the
  // scenario.
  YAML::Node cache(YAML::NodeType::Map);
  cache["field"]["cache"] = std::filesystem::absolute(field_file).string();
  const scenario::Node root = scenario::Node::from_yaml(cache, cohort_name)
                                  .with_fallback(scenario::Node::from_yaml(
                                      layer({{"mesh", subject["mesh"]}, {"field", subject["field"]}}), cohort_name))
                                  .with_fallback(scenario::Node::from_yaml(
                                      layer({{"field", cohort["field"]}, {"outputs", cohort["outputs"]}}), cohort_name))
                                  .with_fallback(scenario::Node::from_yaml(scenario, scenario_name));
  return runner::read_scenario(root, scenario_name);
}

Plan plan(const Cohort& c) {
  Plan p;
  const YAML::Node cohort = parse(c.text, c.file.string());
  const std::string shared = dump(cohort["field"]) + dump(cohort["outputs"]) + fmt::format("{}", c.edge_m.value_or(0));
  for (const Subject& subject : c.subjects) {
    const std::string subject_text = dump(cohort["subjects"][subject.id]);
    std::map<std::string, std::size_t> variants;  // key -> index into p.fields
    for (const ScenarioEntry& entry : c.scenarios) {
      const scenario::Scenario s = job_scenario(c, subject.id, entry.id, "fields" / std::filesystem::path(subject.id));
      const std::string key = field_variant_key(s);
      auto it = variants.find(key);
      if (it == variants.end()) {
        FieldJob job;
        job.subject = subject.id;
        job.id = variant_name(s);
        for (int n = 2; std::any_of(p.fields.begin(), p.fields.end(),
                                    [&](const FieldJob& f) { return f.subject == subject.id && f.id == job.id; });
             ++n) {
          job.id = variant_name(s) + "-" + std::to_string(n);
        }
        job.scenario = entry.id;
        job.inputs = subject.inputs;
        job.inputs.push_back(std::filesystem::absolute(s.field.tissue_file));
        job.digest = digest(fmt::format("{}|{}|{}|{}", subject_text, dump(cohort["field"]), key, c.edge_m.value_or(0)));
        it = variants.emplace(key, p.fields.size()).first;
        p.fields.push_back(std::move(job));
      }
      RunJob run;
      run.subject = subject.id;
      run.scenario = entry.id;
      run.field = p.fields[it->second].id;
      run.inputs = {entry.file};
      run.digest = digest(fmt::format("{}|{}|{}", subject_text, shared,
                                      std::filesystem::absolute(entry.file).lexically_normal().string()));
      p.runs.push_back(std::move(run));
    }
  }
  return p;
}

}  // namespace pneuma::cohort
