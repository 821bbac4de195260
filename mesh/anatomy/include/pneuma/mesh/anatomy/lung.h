#pragma once
// Which lung a surface is: the one lung enum of pneuma (regions, phantom, scenarios).
#include <optional>

namespace pneuma::mesh {

enum class Lung { right, left };

// "Both lungs" where a choice of lungs is optional (the phantom): nothing chosen is both.
inline constexpr std::optional<Lung> kBothLungs = std::nullopt;

}  // namespace pneuma::mesh
