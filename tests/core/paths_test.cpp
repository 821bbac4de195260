#include "pneuma/core/paths.h"

#include <gtest/gtest.h>

#include "pneuma/core/error.h"
#include "test_support.h"

using pneuma::test::TempDir;

TEST(Paths, ReadFileBytesKeepsEveryByte) {
  TempDir dir;
  const std::string bytes("a\0b\r\n\xff", 6);
  const auto file = dir.write("blob.bin", bytes);
  EXPECT_EQ(pneuma::read_file_bytes(file), bytes);
  EXPECT_EQ(pneuma::read_file_bytes(dir.write("empty", "")), "");
}

TEST(Paths, ReadFileBytesRefusesMissingFilesAndFolders) {
  TempDir dir;
  for (const auto& path : {dir / "missing.bin", dir.path()}) {
    try {
      pneuma::read_file_bytes(path);
      ADD_FAILURE() << path << " was read";
    } catch (const pneuma::IoError& e) {
      EXPECT_EQ(std::string(e.what()), path.string() + ": cannot open file");
    }
  }
}

TEST(Paths, ReadFileBytesRefusesDevicesAndFilesOverTheLimit) {
  // /dev/zero never ends: refused before a byte is read.
  try {
    pneuma::read_file_bytes("/dev/zero");
    ADD_FAILURE() << "/dev/zero was read";
  } catch (const pneuma::InputError& e) {
    EXPECT_EQ(std::string(e.what()), "/dev/zero: not a regular file (a device, pipe or socket); expected a file");
  }
  TempDir dir;
  const auto file = dir.write("big.yaml", std::string(100, 'x'));
  EXPECT_EQ(pneuma::read_file_bytes(file, 100).size(), 100u);
  try {
    pneuma::read_file_bytes(file, 99);
    ADD_FAILURE() << "read past the limit";
  } catch (const pneuma::InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              file.string() + ": a file of 100 bytes; expected at most 99 bytes for this kind of file");
  }
}

TEST(Paths, FileStemsListsMatchingRegularFilesSorted) {
  TempDir dir;
  dir.write("stiff.yaml", "");
  dir.write("healthy.yaml", "");
  dir.write("notes.txt", "");
  dir.write("backup.yaml.orig", "");
  std::filesystem::create_directories(dir / "folder.yaml");
  EXPECT_EQ(pneuma::file_stems(dir.path(), ".yaml"), (std::vector<std::string>{"healthy", "stiff"}));
  EXPECT_TRUE(pneuma::file_stems(dir / "missing", ".yaml").empty());
}

TEST(Paths, JoinNamesSeparatesWithCommas) {
  EXPECT_EQ(pneuma::join_names({"a", "b", "c"}), "a, b, c");
  EXPECT_EQ(pneuma::join_names({"only"}), "only");
  EXPECT_EQ(pneuma::join_names({}), "none");
}
