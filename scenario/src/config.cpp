#include "pneuma/scenario/config.h"

#include <algorithm>
#include <map>

#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"
#include "pneuma/core/text.h"

namespace pneuma::scenario {
namespace {

// The largest YAML file read (a scenario, tissue, physiology preset or cohort is a few kB): a
// bigger one is not one of them, and /dev/zero or a pipe never ends (read_file_bytes refuses it).
constexpr std::uintmax_t kMaxYamlBytes = 16u << 20u;

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (std::size_t i = 0; i < items.size(); ++i) out += (i ? ", " : "") + items[i];
  return out;
}

std::string at(const std::string& file, const YAML::Mark& mark) {
  if (mark.is_null() || mark.line < 0) return file;
  return location(file, mark.line, mark.column);
}

YAML::Mark key_mark(const YAML::Node& map, const std::string& key) {
  for (auto it = map.begin(); it != map.end(); ++it) {
    if (it->first.IsScalar() && it->first.Scalar() == key) return it->first.Mark();
  }
  return YAML::Mark::null_mark();
}

// yaml-cpp keeps both entries of a key given twice and answers with the first: a cohort's second
// subject of one id vanished without a word (#49). Refused at the second, in every YAML input.
void refuse_duplicate_keys(const YAML::Node& node, const std::string& file, const std::string& path) {
  if (node.IsSequence()) {
    for (std::size_t i = 0; i < node.size(); ++i) refuse_duplicate_keys(node[i], file, path);
    return;
  }
  if (!node.IsMap()) return;
  std::map<std::string, YAML::Mark> seen;
  for (auto it = node.begin(); it != node.end(); ++it) {
    if (!it->first.IsScalar()) continue;
    const std::string& key = it->first.Scalar();
    std::string key_path = path;
    if (!key_path.empty()) key_path += '.';
    key_path += key;
    const auto [first, inserted] = seen.emplace(key, it->first.Mark());
    if (!inserted) {
      throw InputError(at(file, it->first.Mark()) + ": " + key_path + ": given twice (first at line " +
                       std::to_string(first->second.line + 1) + "): expected each key once");
    }
    refuse_duplicate_keys(it->second, file, key_path);
  }
}

}  // namespace

Node::Node(std::vector<Layer> layers, std::string path) : layers_(std::move(layers)), path_(std::move(path)) {}

Node Node::load_string(const std::string& file_text, const std::string& name) {
  const std::string_view text = without_bom(file_text);
  // YAML is UTF-8 text; bytes that are not would reach the outputs' JSON and HTML (the scenario
  // name in manifest.json) and fail there, after the run.
  if (const std::optional<std::size_t> bad = first_invalid_utf8(text)) {
    const std::size_t line_start = text.rfind('\n', *bad) == std::string::npos ? 0 : text.rfind('\n', *bad) + 1;
    const auto line0 = static_cast<int>(std::count(text.begin(), text.begin() + *bad, '\n'));
    throw InputError(location(name, line0, static_cast<int>(*bad - line_start)) +
                     ": expected UTF-8 text, got the byte " + quote_bytes(text.substr(*bad, 1)));
  }
  YAML::Node root;
  try {
    root = YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    throw InputError(at(name, e.mark) + ": not valid YAML: " + e.msg);
  }
  refuse_duplicate_keys(root, name, "");
  return from_yaml(root, name);
}

Node Node::from_yaml(const YAML::Node& root, const std::string& name) {
  if (!root.IsMap()) {
    throw InputError(at(name, root.Mark()) + ": expected a YAML mapping of keys at the top level");
  }
  return Node({Layer{root, std::make_shared<const std::string>(name), std::make_shared<std::set<std::string>>()}}, "");
}

Node Node::load_file(const std::filesystem::path& path) {
  return load_string(read_file_bytes(path, kMaxYamlBytes), path.string());
}

std::filesystem::path Node::directory(const std::string& key) const {
  const Layer* layer = key.empty() ? &layers_.front() : layer_with(key);
  if (!layer) layer = &layers_.front();
  return std::filesystem::path(*layer->file).parent_path();
}

const Node::Layer* Node::layer_with(const std::string& key) const {
  asked_keys_->insert(key);
  for (const Layer& layer : layers_) {
    if (layer.node.IsMap() && layer.node[key]) return &layer;
  }
  return nullptr;
}

bool Node::has(const std::string& key) const { return layer_with(key) != nullptr; }

bool Node::is_map(const std::string& key) const {
  const Layer* layer = layer_with(key);
  return layer != nullptr && layer->node[key].IsMap();
}

YAML::Node Node::child(const std::string& key, const Layer** found) const {
  const Layer* layer = layer_with(key);
  if (!layer) return YAML::Node(YAML::NodeType::Undefined);
  layer->read_keys->insert(key);
  if (found) *found = layer;
  return layer->node[key];
}

std::string Node::child_path(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

std::string Node::value_where(const std::string& key) const {
  const Layer* layer = layer_with(key);
  if (!layer) return at(file(), layers_.front().node.Mark()) + ": " + child_path(key);
  return at(*layer->file, layer->node[key].Mark()) + ": " + child_path(key);
}

void Node::fail(const std::string& message) const {
  throw InputError(at(file(), layers_.front().node.Mark()) + ": " + (path_.empty() ? "" : path_ + ": ") + message);
}

void Node::fail_at(const std::string& key, const std::string& message) const {
  throw InputError(value_where(key) + ": " + message);
}

void Node::fail_missing(const std::string& message) const {
  if (via_.empty() || layers_.size() < 2 || !layer_with(via_)) fail(message);
  throw InputError(value_where(via_) + ": " + *layers_.back().file + ": " + message + ", and " +
                   (path_.empty() ? std::string("the file") : path_) + " does not give it either");
}

Node Node::map(const std::string& key) const {
  auto node = optional_map(key);
  if (!node) fail_missing("missing key '" + key + "'");
  return *node;
}

std::optional<Node> Node::optional_map(const std::string& key) const {
  asked_keys_->insert(key);
  std::vector<Layer> layers;
  bool first = true;
  for (const Layer& layer : layers_) {
    if (!layer.node.IsMap() || !layer.node[key]) continue;
    layer.read_keys->insert(key);
    YAML::Node value = layer.node[key];
    if (!value.IsMap()) {
      // A non-mapping in front hides what is behind it; a non-mapping behind is ignored.
      if (first) fail_at(key, "expected a mapping of keys");
      continue;
    }
    layers.push_back(Layer{value, layer.file, std::make_shared<std::set<std::string>>()});
    first = false;
  }
  if (layers.empty()) return std::nullopt;
  return Node(std::move(layers), child_path(key));
}

std::vector<Node> Node::sequence(const std::string& key) const {
  const Layer* layer = nullptr;
  YAML::Node value = child(key, &layer);
  std::vector<Node> items;
  if (!value) return items;
  if (!value.IsSequence()) fail_at(key, "expected a list");
  for (std::size_t i = 0; i < value.size(); ++i) {
    items.push_back(Node({Layer{value[i], layer->file, std::make_shared<std::set<std::string>>()}},
                         child_path(key) + "[" + std::to_string(i) + "]"));
  }
  return items;
}

std::string Node::scalar(const std::string& key, const char* expected) const {
  YAML::Node value = child(key);
  if (!value) fail_missing("missing key '" + key + "' (" + expected + ")");
  if (!value.IsScalar()) fail_at(key, std::string(expected) + ", got a " + (value.IsMap() ? "mapping" : "list"));
  return value.Scalar();
}

double Node::quantity(const std::string& key, const units::Kind& kind) const {
  const std::string example = std::string("expected ") + kind.name + " such as '" + kind.example + "'";
  const std::string text = scalar(key, example.c_str());
  try {
    return units::parse(text, kind);
  } catch (const units::UnitError& e) {
    fail_at(key, e.what());
  }
}

std::optional<double> Node::optional_quantity(const std::string& key, const units::Kind& kind) const {
  if (!has(key)) return std::nullopt;
  return quantity(key, kind);
}

double Node::positive_quantity(const std::string& key, const units::Kind& kind) const {
  const double value = quantity(key, kind);
  if (!(value > 0))
    fail_at(key, std::string("expected a positive ") + kind.name + ", got " + quote_input(child(key).Scalar()));
  return value;
}

double Node::ratio(const std::string& key) const {
  const std::string text = scalar(key, "expected a ratio such as '1:2'");
  try {
    return units::parse_ratio(text);
  } catch (const units::UnitError& e) {
    fail_at(key, e.what());
  }
}

std::optional<double> Node::optional_ratio(const std::string& key) const {
  if (!has(key)) return std::nullopt;
  return ratio(key);
}

std::string Node::string(const std::string& key) const { return scalar(key, "expected a text value"); }

std::optional<std::string> Node::optional_string(const std::string& key) const {
  if (!has(key)) return std::nullopt;
  return string(key);
}

std::string Node::choice(const std::string& key, const std::vector<std::string>& choices) const {
  std::string value = scalar(key, ("expected one of: " + join(choices)).c_str());
  for (const auto& c : choices) {
    if (c == value) return value;
  }
  fail_at(key, "expected one of: " + join(choices) + "; got " + quote_input(value));
}

bool Node::boolean(const std::string& key, bool fallback) const {
  if (!has(key)) return fallback;
  const std::string value = scalar(key, "expected true or false");
  if (value == "true" || value == "yes" || value == "on") return true;
  if (value == "false" || value == "no" || value == "off") return false;
  fail_at(key, "expected true or false, got " + quote_input(value));
}

namespace {

// The whole number `text` holds within [min_value, max_value], or nothing.
std::optional<long> whole_number(const std::string& text, long min_value, long max_value) {
  std::size_t used = 0;
  long parsed = 0;
  try {
    parsed = std::stol(text, &used);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (used != text.size() || text.empty() || parsed < min_value || parsed > max_value) return std::nullopt;
  return parsed;
}

std::string whole_number_expected(long min_value, long max_value, const std::string& got) {
  return "expected a whole number from " + std::to_string(min_value) + " to " + std::to_string(max_value) + ", got " +
         quote_input(got);
}

}  // namespace

long Node::integer(const std::string& key, long fallback, long min_value, long max_value) const {
  if (!has(key)) return fallback;
  const std::string value = scalar(key, "expected a whole number");
  const auto parsed = whole_number(value, min_value, max_value);
  if (!parsed) fail_at(key, whole_number_expected(min_value, max_value, value));
  return *parsed;
}

long Node::as_integer(long min_value, long max_value) const {
  const YAML::Node& value = layers_.front().node;
  if (!value.IsScalar()) fail(whole_number_expected(min_value, max_value, value.IsMap() ? "a mapping" : "a list"));
  const auto parsed = whole_number(value.Scalar(), min_value, max_value);
  if (!parsed) fail(whole_number_expected(min_value, max_value, value.Scalar()));
  return *parsed;
}

std::string Node::as_scalar(const std::string& expected) const {
  const YAML::Node& value = layers_.front().node;
  if (!value.IsScalar() || value.Scalar().empty()) {
    fail(expected + ", got " + (value.IsMap() ? "a mapping" : value.IsSequence() ? "a list" : "nothing"));
  }
  return value.Scalar();
}

std::vector<std::string> Node::keys() const {
  std::vector<std::string> out;
  std::set<std::string> seen;
  for (const Layer& layer : layers_) {
    if (!layer.node.IsMap()) continue;
    for (auto it = layer.node.begin(); it != layer.node.end(); ++it) {
      const std::string key = it->first.Scalar();
      layer.read_keys->insert(key);
      if (seen.insert(key).second) out.push_back(key);
    }
  }
  return out;
}

void Node::accept(const std::string& key) const {
  asked_keys_->insert(key);
  for (const Layer& layer : layers_) layer.read_keys->insert(key);
}

void Node::finish() const {
  for (const Layer& layer : layers_) {
    if (!layer.node.IsMap()) continue;
    for (auto it = layer.node.begin(); it != layer.node.end(); ++it) {
      const std::string key = it->first.Scalar();
      bool read = false;
      for (const Layer& any : layers_) read = read || any.read_keys->count(key) > 0;
      if (!read) {
        throw InputError(at(*layer.file, key_mark(layer.node, key)) + ": " + child_path(key) +
                         ": unknown key; expected one of: " +
                         join(std::vector<std::string>(asked_keys_->begin(), asked_keys_->end())));
      }
    }
  }
}

Node Node::with_fallback(const Node& fallback, const std::string& via) const {
  std::vector<Layer> layers;
  layers.reserve(layers_.size() + fallback.layers_.size());
  for (const auto* from : {&layers_, &fallback.layers_}) {
    for (const Layer& layer : *from) layers.push_back(layer);
  }
  Node layered(std::move(layers), path_);
  layered.via_ = via;
  return layered;
}

}  // namespace pneuma::scenario
