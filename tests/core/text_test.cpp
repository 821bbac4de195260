#include "pneuma/core/text.h"

#include <gtest/gtest.h>

#include <string>

using namespace std::string_literals;

TEST(Text, FirstInvalidUtf8FindsTheFirstBadByte) {
  EXPECT_EQ(pneuma::first_invalid_utf8("plain ascii"), std::nullopt);
  EXPECT_EQ(pneuma::first_invalid_utf8("lung \xc3\xa9t\xc3\xa9 \xe2\x86\x92 \xf0\x9f\xab\x81"), std::nullopt);
  EXPECT_EQ(pneuma::first_invalid_utf8("ab\xff"), 2u);
  EXPECT_EQ(pneuma::first_invalid_utf8("a\xc3"), 1u) << "a sequence cut short";
  EXPECT_EQ(pneuma::first_invalid_utf8("\xc0\xaf"), 0u) << "an overlong '/'";
  EXPECT_EQ(pneuma::first_invalid_utf8("x\xed\xa0\x80"), 1u) << "a surrogate";
  EXPECT_EQ(pneuma::first_invalid_utf8("\xf4\x90\x80\x80"), 0u) << "above U+10FFFF";
}

TEST(Text, QuoteBytesWritesUnprintableBytesAsHexAndKeepsUtf8) {
  EXPECT_EQ(pneuma::quote_bytes("name: a\x1b[31mb"), "name: a\\x1b[31mb");
  EXPECT_EQ(pneuma::quote_bytes("form\ffeed\nline\x7f"), "form\\x0cfeed\\x0aline\\x7f");
  EXPECT_EQ(pneuma::quote_bytes("nul\0here"s), "nul\\x00here") << "not cut at a NUL byte";
  EXPECT_EQ(pneuma::quote_bytes("bad \xff\xfe end"), "bad \\xff\\xfe end");
  EXPECT_EQ(pneuma::quote_bytes("caf\xc3\xa9\ttab"), "caf\xc3\xa9\ttab");
}

// #49: a byte-order mark and other invisible characters are written out in messages, and what a
// message quotes is cut to 80 bytes with the total (never inside a UTF-8 sequence).
TEST(Text, InvisibleCharactersAreWrittenOutAndLongQuotesAreCut) {
  EXPECT_EQ(pneuma::quote_bytes("\xEF\xBB\xBF[Header]"), "\\u{FEFF}[Header]");
  EXPECT_EQ(pneuma::quote_bytes("a\xE2\x80\x8B"
                                "b\xC2\xA0"
                                "c"),
            "a\\u{200B}b\\u{00A0}c");
  EXPECT_EQ(pneuma::quote_bytes("\xC3\xA9t\xC3\xA9"), "\xC3\xA9t\xC3\xA9");  // été stays
  EXPECT_EQ(pneuma::quote_input("2 s"), "'2 s'");
  EXPECT_EQ(pneuma::quote_input(std::string(80, 'a')), "'" + std::string(80, 'a') + "'");
  const std::string ten_megabytes(10000000, 'a');  // NOLINT(bugprone-string-constructor): that large on purpose
  EXPECT_EQ(pneuma::quote_input(ten_megabytes), "'" + std::string(80, 'a') + "...' (10000000 bytes)");
  // 79 ASCII bytes, then a two-byte letter that would end at byte 81: cut before it.
  EXPECT_EQ(pneuma::quote_input(std::string(79, 'a') + "\xC3\xA9\xC3\xA9"),
            "'" + std::string(79, 'a') + "...' (83 bytes)");
  EXPECT_EQ(pneuma::without_bom("\xEF\xBB\xBFx"), "x");
  EXPECT_EQ(pneuma::without_bom("x\xEF\xBB\xBF"), "x\xEF\xBB\xBF");
}
