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
