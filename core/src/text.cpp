#include "pneuma/core/text.h"

#include <algorithm>
#include <cstdint>
#include <cstdio>

namespace pneuma {
namespace {

// The length of the well-formed UTF-8 sequence at `at` (1 to 4), or 0 when there is none.
std::size_t utf8_sequence_length(std::string_view text, std::size_t at) {
  const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(text[i]); };
  const unsigned char lead = byte(at);
  if (lead < 0x80) return 1;
  std::size_t length = 0;
  unsigned char low = 0x80, high = 0xBF;  // the allowed range of the second byte
  if (lead >= 0xC2 && lead <= 0xDF) {
    length = 2;
  } else if (lead >= 0xE0 && lead <= 0xEF) {
    length = 3;
    if (lead == 0xE0) low = 0xA0;   // overlong
    if (lead == 0xED) high = 0x9F;  // surrogates
  } else if (lead >= 0xF0 && lead <= 0xF4) {
    length = 4;
    if (lead == 0xF0) low = 0x90;   // overlong
    if (lead == 0xF4) high = 0x8F;  // above U+10FFFF
  } else {
    return 0;
  }
  if (at + length > text.size()) return 0;
  if (byte(at + 1) < low || byte(at + 1) > high) return 0;
  for (std::size_t i = 2; i < length; ++i) {
    if (byte(at + i) < 0x80 || byte(at + i) > 0xBF) return 0;
  }
  return length;
}

// Characters that print as nothing (or as a blank that looks like a space) on a terminal.
bool invisible(std::uint32_t c) {
  return c == 0x00A0 || c == 0x00AD || c == 0x034F || c == 0x061C || (c >= 0x200B && c <= 0x200F) ||
         (c >= 0x2028 && c <= 0x202F) || (c >= 0x2060 && c <= 0x206F) || c == 0x3164 || c == 0xFEFF ||
         (c >= 0xFFF0 && c <= 0xFFF8);
}

std::uint32_t code_point(std::string_view sequence) {
  const auto byte = [&](std::size_t i) { return static_cast<std::uint32_t>(static_cast<unsigned char>(sequence[i])); };
  switch (sequence.size()) {
    case 2: return ((byte(0) & 0x1F) << 6) | (byte(1) & 0x3F);
    case 3: return ((byte(0) & 0x0F) << 12) | ((byte(1) & 0x3F) << 6) | (byte(2) & 0x3F);
    case 4: return ((byte(0) & 0x07) << 18) | ((byte(1) & 0x3F) << 12) | ((byte(2) & 0x3F) << 6) | (byte(3) & 0x3F);
    default: return byte(0);
  }
}

}  // namespace

std::optional<std::size_t> first_invalid_utf8(std::string_view text) {
  for (std::size_t at = 0; at < text.size();) {
    const std::size_t length = utf8_sequence_length(text, at);
    if (length == 0) return at;
    at += length;
  }
  return std::nullopt;
}

std::string quote_bytes(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t at = 0; at < text.size();) {
    const auto c = static_cast<unsigned char>(text[at]);
    const std::size_t length = utf8_sequence_length(text, at);
    if (length == 1 && (c >= 0x20 || c == '\t') && c != 0x7F) {
      out += static_cast<char>(c);
    } else if (length > 1) {
      const std::string_view sequence = text.substr(at, length);
      if (invisible(code_point(sequence))) {
        char hex[16];
        std::snprintf(hex, sizeof hex, "\\u{%04X}", static_cast<unsigned>(code_point(sequence)));
        out += hex;
      } else {
        out.append(sequence);
      }
      at += length;
      continue;
    } else {
      constexpr const char* kHex = "0123456789abcdef";
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 0xF];
    }
    ++at;
  }
  return out;
}

std::string quote_input(std::string_view text) {
  // Appended piece by piece (GCC 12 warns, wrongly, on `"'" + std::string&&` here).
  std::string out(1, '\'');
  if (text.size() <= kQuotedLength) return out.append(text).append("'");
  std::size_t cut = 0;
  while (cut < text.size()) {
    const std::size_t length = std::max<std::size_t>(utf8_sequence_length(text, cut), 1);
    if (cut + length > kQuotedLength) break;
    cut += length;
  }
  return out.append(text.substr(0, cut)).append("...' (").append(std::to_string(text.size())).append(" bytes)");
}

std::string_view without_bom(std::string_view text) { return text.starts_with("\xEF\xBB\xBF") ? text.substr(3) : text; }

}  // namespace pneuma
