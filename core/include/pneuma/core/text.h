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
// (control characters, newlines, DEL, NUL, bytes outside well-formed UTF-8) and every invisible
// character as "\u{FEFF}" (a byte-order mark, zero-width and direction marks, soft hyphen,
// no-break space); other well-formed UTF-8 and tabs are kept. cli/main.cpp prints every error
// message through it.
std::string quote_bytes(std::string_view text);

// User text as a message quotes it, in single quotes: whole up to kQuotedLength bytes, else cut
// there (never inside a UTF-8 sequence) with the total: "'aaaa...' (10485760 bytes)". A 10 MB
// field made a 10 MB message line (#49). Every message that quotes input text goes through it.
inline constexpr std::size_t kQuotedLength = 80;
std::string quote_input(std::string_view text);

// `text` without a leading UTF-8 byte-order mark (Excel's "CSV UTF-8" writes one): every text
// reader takes it.
std::string_view without_bom(std::string_view text);

}  // namespace pneuma
