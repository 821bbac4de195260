#include <algorithm>
#include <string>

#include "commands.h"
#include "pneuma/core/error.h"
#include "pneuma/core/units.h"

namespace pneuma::cli {

namespace {
// "3 mm" -> "3mm": a placeholder that reads as an example, not as a default.
std::string compact(std::string text) {
  text.erase(std::remove(text.begin(), text.end(), ' '), text.end());
  return text;
}
}  // namespace

CLI::Option* add_quantity_option(CLI::App& command, const std::string& name, double& value_si,
                                 const std::string& description, const char* kind_name) {
  static const std::pair<const char*, const units::Kind*> kKinds[] = {{"length", &units::kind::length},
                                                                      {"duration", &units::kind::duration},
                                                                      {"rate", &units::kind::rate},
                                                                      {"pressure", &units::kind::pressure},
                                                                      {"volume", &units::kind::volume}};
  const units::Kind* kind = nullptr;
  for (const auto& [n, k] : kKinds) {
    if (std::string(n) == kind_name) kind = k;
  }
  return command
      .add_option_function<std::string>(
          name,
          [&value_si, kind, name](const std::string& text) {
            try {
              value_si = units::parse(text, *kind);
            } catch (const units::UnitError& e) {
              throw UsageError("pneuma: " + name + ": " + e.what());
            }
          },
          description)
      ->type_name(std::string("<") + kind_name + ", e.g. " + compact(kind->example) + ">");
}

void check_option(const std::string& option, const parameters::Parameter& parameter, double value) {
  if (const auto why = parameter.check(value)) throw UsageError("pneuma: " + option + ": " + *why);
}

void add_examples(CLI::App& command, std::initializer_list<const char*> lines) {
  std::string footer = "\nExamples:\n";
  for (const char* line : lines) footer += std::string("  ") + line + "\n";
  command.footer(footer);
}

}  // namespace pneuma::cli
