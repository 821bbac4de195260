#pragma once
// The displacement overlay's colour map (viridis) and its legend, drawn on the CPU into the
// read-back image. One table serves the shader (its GLSL text is generated from it) and the
// legend, so the colour bar shows exactly the colours of the mesh.
#include <string>

#include "pneuma/render/image.h"

namespace pneuma::render::detail {

// Viridis (matplotlib), sampled at 9 evenly spaced points, sRGB 0..255.
inline constexpr int kViridisSamples = 9;
extern const unsigned char kViridis[kViridisSamples][3];

// sRGB colour of viridis at t in [0, 1] (linear interpolation between the samples).
Rgba viridis(double t);

// GLSL: `vec3 viridis_srgb(float t)` doing the same interpolation.
std::string viridis_glsl();

// Draws a vertical colour bar at the right edge with its top value (metres, shown in mm) and 0
// in a built-in 5x7 font. Does nothing on images too small to hold it.
void draw_legend(Image& image, double max_m);

// Draws `text` (digits, '.', '-', 'm', ' ') with its top-left corner at (x, y), each font
// pixel `scale` image pixels wide. Returns the width drawn.
int draw_text(Image& image, int x, int y, const std::string& text, int scale, Rgba colour);
int text_width(const std::string& text, int scale);

}  // namespace pneuma::render::detail
