#include "pneuma/core/atomic_file.h"

#include <gtest/gtest.h>

#include "pneuma/core/error.h"
#include "test_support.h"

using pneuma::test::TempDir;

TEST(AtomicFile, WritesUnderTheFinalNameOnlyWhenComplete) {
  TempDir dir;
  const auto target = dir / "sub/out.txt";
  pneuma::write_stream_atomically(target, false, [](std::ostream& out) { out << "hello\n"; });
  EXPECT_EQ(pneuma::test::read_text(target), "hello\n");
  EXPECT_EQ(dir.files(), std::vector<std::string>{"sub/out.txt"});
}

TEST(AtomicFile, AFailedWriteLeavesNoFileAndKeepsTheOldOne) {
  TempDir dir;
  const auto target = dir.write("out.txt", "old");
  EXPECT_THROW(pneuma::write_stream_atomically(target, false,
                                               [](std::ostream& out) {
                                                 out << "partial";
                                                 throw pneuma::IoError("disk full");
                                               }),
               pneuma::IoError);
  EXPECT_EQ(pneuma::test::read_text(target), "old");
  EXPECT_EQ(dir.files(), std::vector<std::string>{"out.txt"});
}
