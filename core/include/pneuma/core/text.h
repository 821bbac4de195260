#pragma once
// Text from input files shown in messages, and the UTF-8 check of text that goes into JSON, HTML
// and YAML outputs. A message is one printable line: bytes from the input that are not printable
// (control characters, bytes that are not UTF-8, NUL) are written as "\x1b", never copied raw.
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace pneuma {

// The offset of the first byte of `text` that does not start a well-formed UTF-8 sequence
// (overlong forms, surrogates and code points above U+10FFFF included); nullopt when all are.
std::optional<std::size_t> first_invalid_utf8(std::string_view text);

// `text` with every byte that would not print as itself on a terminal written as "\xHH"
// (control characters, newlines, DEL, NUL, bytes outside well-formed UTF-8); well-formed UTF-8
// beyond ASCII and tabs are kept. cli/main.cpp prints every error message through it.
std::string quote_bytes(std::string_view text);

}  // namespace pneuma
