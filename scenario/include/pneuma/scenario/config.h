#pragma once
// A thin layer over yaml-cpp that reads configuration values with units into SI and reports
// every bad value as one line:
//   scenarios/x.yaml:7:14: physiology.compliance: expected a compliance such as '0.1 L/cmH2O', got '0.1'
// Keys are tracked: finish() refuses any key nobody read, so a typo is never silently ignored.
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/core/units.h"

namespace pneuma::scenario {

// One YAML mapping (or scalar/sequence) with the file it came from and its key path.
class Node {
 public:
  // Loads a YAML file. Throws IoError when it cannot be read, InputError when it is not YAML
  // or its top level is not a mapping.
  static Node load_file(const std::filesystem::path& path);
  // Parses YAML text; `name` stands for the file in messages.
  static Node load_string(const std::string& text, const std::string& name);
  // Wraps a YAML tree built in memory (e.g. from a Python dict): its nodes have no positions,
  // so messages read "<name>: <key path>: <what was expected>". Throws InputError when the top
  // level is not a mapping.
  static Node from_yaml(const YAML::Node& root, const std::string& name);

  const std::string& file() const { return *layers_.front().file; }
  const std::string& path() const { return path_; }  // "physiology.driver"
  // Folder of the file that holds `key` (or of this node), for paths relative to it.
  std::filesystem::path directory(const std::string& key = "") const;

  bool has(const std::string& key) const;
  // True when `key` holds a mapping (rather than a scalar or a list).
  bool is_map(const std::string& key) const;
  // The child mapping at `key`; throws when missing or not a mapping.
  Node map(const std::string& key) const;
  std::optional<Node> optional_map(const std::string& key) const;
  // The items of the sequence at `key` (each item may be any node).
  std::vector<Node> sequence(const std::string& key) const;

  // A quantity with its unit, in SI.
  double quantity(const std::string& key, const units::Kind& kind) const;
  std::optional<double> optional_quantity(const std::string& key, const units::Kind& kind) const;
  // A quantity with a lower/upper bound check (inclusive unless stated).
  double positive_quantity(const std::string& key, const units::Kind& kind) const;
  // "1:2" -> 0.5
  double ratio(const std::string& key) const;
  std::optional<double> optional_ratio(const std::string& key) const;
  std::string string(const std::string& key) const;
  std::optional<std::string> optional_string(const std::string& key) const;
  // One of `choices`; the message lists them.
  std::string choice(const std::string& key, const std::vector<std::string>& choices) const;
  bool boolean(const std::string& key, bool fallback) const;
  long integer(const std::string& key, long fallback, long min_value, long max_value) const;
  // This node itself as a whole number (an item of a list such as `values: [3, 4, 5]`).
  long as_integer(long min_value, long max_value) const;
  // This node itself as text (a scalar item of a list); `expected` says what, when it is not one.
  std::string as_scalar(const std::string& expected) const;

  // Throws for the first key of this mapping that was never read.
  void finish() const;

  // A one-line error at this node ("file:l:c: path: message").
  [[noreturn]] void fail(const std::string& message) const;
  // A one-line error at the value of `key`.
  [[noreturn]] void fail_at(const std::string& key, const std::string& message) const;
  // Where the value of `key` is ("file:l:c: path.key"), for an error found after loading (a check
  // that needs the compiled model) that must still name the key.
  std::string value_where(const std::string& key) const;
  // A key this node needs and neither it nor its fallback gives (`message`: "missing key 'x'
  // (expected ...)"): for a node made by with_fallback(fallback, via), at the key `via` that named
  // the fallback (a scenario's `preset:`), naming the fallback's file; else as fail().
  [[noreturn]] void fail_missing(const std::string& message) const;

  // Keys of this mapping (marks them read; for maps whose keys are data, e.g. region labels).
  std::vector<std::string> keys() const;
  // Marks `key` as read without reading it (for keys handled elsewhere, e.g. by a preset).
  void accept(const std::string& key) const;

  // This node with `fallback` behind it: a key missing here is looked up there (presets).
  // Both layers are checked by finish(), and messages name the file each value came from;
  // `via`: the key of this node that named the fallback, where a key missing in both is reported.
  Node with_fallback(const Node& fallback, const std::string& via = {}) const;

 private:
  struct Layer {
    Layer(const YAML::Node& node_, std::shared_ptr<const std::string> file_,
          std::shared_ptr<std::set<std::string>> read_keys_)
        : node(node_), file(std::move(file_)), read_keys(std::move(read_keys_)) {}
    Layer(const Layer&) = default;
    Layer(Layer&&) = default;
    // Not assignable: YAML::Node's operator= does not rebind a handle, it makes the node the
    // handle points to (shared with every other handle on it) refer to another node, and may
    // throw. So a Node, a list of layers, is copied but never assigned.
    Layer& operator=(const Layer&) = delete;
    Layer& operator=(Layer&&) = delete;

    YAML::Node node;
    std::shared_ptr<const std::string> file;
    std::shared_ptr<std::set<std::string>> read_keys;
  };
  Node(std::vector<Layer> layers, std::string path);
  // The layer holding `key`, or nullptr.
  const Layer* layer_with(const std::string& key) const;
  YAML::Node child(const std::string& key, const Layer** layer = nullptr) const;
  std::string child_path(const std::string& key) const;
  std::string scalar(const std::string& key, const char* expected) const;

  std::vector<Layer> layers_;  // front: the node itself; back: its deepest fallback
  std::string path_;
  std::string via_;  // the key that named the fallback layers (with_fallback), or empty
  // Every key this node was asked for, present or not: the list an unknown key is told of.
  std::shared_ptr<std::set<std::string>> asked_keys_ = std::make_shared<std::set<std::string>>();
};

}  // namespace pneuma::scenario
