// ChebyshevTable against functions known in closed form: a polynomial of low degree is reproduced
// to rounding, an entire function converges to the tolerance, a kink in the range gives no table.
#include "pneuma/core/chebyshev.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using pneuma::ChebyshevTable;

namespace {

double at(const ChebyshevTable& table, double x) {
  double value = 0.0;
  table.evaluate(x, {&value, 1});
  return value;
}

}  // namespace

TEST(ChebyshevTable, ReproducesACubicAtTheFirstRefinement) {
  int calls = 0;
  const auto cubic = [](double x) { return 2.0 - 3.0 * x + 0.5 * x * x + 0.25 * x * x * x; };
  const auto table = ChebyshevTable::fit(
      [&](double x, std::span<double> v) {
        ++calls;
        v[0] = cubic(x);
      },
      1, -1.5, 2.0, 1e-13);
  ASSERT_TRUE(table.has_value());
  EXPECT_EQ(calls, 33);  // 17 points, then the 16 that check them
  EXPECT_EQ(table->intervals(), 32u);
  for (double x = -1.5; x <= 2.0; x += 0.0173) EXPECT_NEAR(at(*table, x), cubic(x), 1e-13 * 6.0) << x;
  EXPECT_EQ(at(*table, 2.0), cubic(2.0));  // a node: the sample itself
}

TEST(ChebyshevTable, ConvergesForAnEntireFunctionOfEveryComponent) {
  const auto table = ChebyshevTable::fit(
      [](double x, std::span<double> v) {
        v[0] = std::exp(x);
        v[1] = std::sin(5.0 * x);
      },
      2, 0.0, 3.0, 1e-13);
  ASSERT_TRUE(table.has_value());
  EXPECT_LE(table->estimated_error(), 1e-13);
  double worst_exp = 0.0, worst_sin = 0.0;
  for (double x = 0.0; x <= 3.0; x += 0.001) {
    double v[2];
    table->evaluate(x, v);
    worst_exp = std::max(worst_exp, std::abs(v[0] - std::exp(x)) / std::exp(3.0));
    worst_sin = std::max(worst_sin, std::abs(v[1] - std::sin(5.0 * x)));
  }
  EXPECT_LT(worst_exp, 1e-14);
  EXPECT_LT(worst_sin, 1e-13);
}

TEST(ChebyshevTable, NoTableWhereTheFunctionHasAKinkOrTheRangeIsNotFinite) {
  const auto kink = [](double x, std::span<double> v) { v[0] = std::abs(x - 0.3); };
  EXPECT_FALSE(ChebyshevTable::fit(kink, 1, -1.0, 1.0, 1e-12).has_value());
  EXPECT_FALSE(ChebyshevTable::fit(kink, 1, 1.0, -1.0, 1e-12).has_value());
  EXPECT_FALSE(ChebyshevTable::fit(kink, 1, 0.0, INFINITY, 1e-12).has_value());
  // Away from the kink it is smooth (linear).
  EXPECT_TRUE(ChebyshevTable::fit(kink, 1, 0.5, 1.0, 1e-12).has_value());
}

TEST(ChebyshevTable, OnePointRange) {
  const auto table = ChebyshevTable::fit([](double x, std::span<double> v) { v[0] = 7.0 * x; }, 1, 0.5, 0.5, 1e-12);
  ASSERT_TRUE(table.has_value());
  EXPECT_TRUE(table->covers(0.5));
  EXPECT_FALSE(table->covers(0.5000001));
  EXPECT_EQ(at(*table, 0.5), 3.5);
}
