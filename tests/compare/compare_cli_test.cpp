// `pneuma compare` end to end: files written, and one-line errors with exit code 2.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>

#include "test_support.h"

using pneuma::test::count_lines;
using pneuma::test::read_text;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

TEST(CompareCli, Fig6QuickWritesCsvAndSvg) {
  TempDir dir;
  const auto out = dir / "figures";
  const auto r = run_pneuma({"compare", "fig6", "-o", out.string(), "--quick"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_EQ(count_lines(out / "fig6.csv"), 1 + 11 * 11);
  EXPECT_EQ(read_text(out / "fig6.csv").rfind("vertex,row,column,proposed,", 0), 0u);
  const std::string svg = read_text(out / "fig6.svg");
  EXPECT_EQ(svg.rfind("<svg ", 0), 0u);
  EXPECT_NE(r.out.find("wrote "), std::string::npos);
}

TEST(CompareCli, AllQuickWritesEveryFigureDeterministically) {
  TempDir a, b;
  ASSERT_EQ(run_pneuma({"compare", "all", "-o", a.path().string(), "--quick", "-q"}).exit_code, 0);
  ASSERT_EQ(run_pneuma({"compare", "all", "-o", b.path().string(), "--quick", "-q"}).exit_code, 0);
  const std::vector<std::string> expected{"fig2.csv", "fig2.svg", "fig6.csv", "fig6.svg",   "fig7.csv",
                                          "fig7.svg", "fig8.csv", "fig8.svg", "table1.csv", "table1.svg"};
  std::vector<std::string> written = a.files();
  std::sort(written.begin(), written.end());
  EXPECT_EQ(written, expected);
  for (const auto& name : expected) EXPECT_EQ(read_text(a / name), read_text(b / name)) << name;
}

TEST(CompareCli, UnknownFigureIsOneLineAndExitCode2) {
  TempDir dir;
  const auto r = run_pneuma({"compare", "fig9", "-o", dir.path().string()});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "pneuma: compare: unknown figure 'fig9' (expected fig2, fig6, fig7, fig8, table1, or all)\n");
  EXPECT_TRUE(r.out.empty());
  EXPECT_TRUE(dir.files().empty()) << "nothing written";
}

TEST(CompareCli, EvenGridSideIsRejected) {
  TempDir dir;
  const auto r = run_pneuma({"compare", "fig6", "-o", dir.path().string(), "--grid-side", "10"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "pneuma: compare: --grid-side: expected an odd number >= 3, got 10\n");
}
