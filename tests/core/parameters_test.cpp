#include "pneuma/core/parameters.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace p = pneuma::parameters;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// The first double past `value` towards `direction`: the closest values either side of a bound.
double past(double value, double direction) { return std::nextafter(value, direction); }

}  // namespace

// Oracle: the rules as the documentation states them (README, Limits): an edge of at least 0.1 mm,
// a field tolerance from 1e-12 to below 1, a clique of 1 to 4 hops, a positive area unit.
TEST(Parameters, EachRuleTakesExactlyItsDocumentedRange) {
  EXPECT_TRUE(p::kEdge.accepts(1e-4));
  EXPECT_FALSE(p::kEdge.accepts(past(1e-4, 0.0)));
  EXPECT_TRUE(p::kEdge.accepts(1.0));

  EXPECT_TRUE(p::kFieldTolerance.accepts(1e-12));
  EXPECT_FALSE(p::kFieldTolerance.accepts(past(1e-12, 0.0)));
  EXPECT_TRUE(p::kFieldTolerance.accepts(past(1.0, 0.0)));
  EXPECT_FALSE(p::kFieldTolerance.accepts(1.0));

  for (int hops = 1; hops <= 4; ++hops) EXPECT_TRUE(p::kCliqueHops.accepts(hops)) << hops;
  EXPECT_FALSE(p::kCliqueHops.accepts(0.0));
  EXPECT_FALSE(p::kCliqueHops.accepts(5.0));
  EXPECT_FALSE(p::kCliqueHops.accepts(2.5));  // a count

  EXPECT_FALSE(p::kAreaUnit.accepts(0.0));
  EXPECT_TRUE(p::kAreaUnit.accepts(std::numeric_limits<double>::denorm_min()));

  // No rule takes what is not a number; an unbounded end is no licence for infinity.
  for (const p::Parameter* parameter : {&p::kEdge, &p::kFieldTolerance, &p::kCliqueHops, &p::kAreaUnit}) {
    EXPECT_FALSE(parameter->accepts(kNaN)) << parameter->name;
    EXPECT_FALSE(parameter->accepts(kInf)) << parameter->name;
    EXPECT_FALSE(parameter->accepts(-kInf)) << parameter->name;
    EXPECT_TRUE(parameter->accepts(parameter->default_si)) << parameter->name;
  }
}

TEST(Parameters, MessagesStateTheRangeInTheUnitUsersWrite) {
  EXPECT_EQ(p::kEdge.check(5e-5), "expected an edge of at least 0.1 mm, got 0.05 mm");
  EXPECT_EQ(p::kEdge.check(-1e-3), "expected an edge of at least 0.1 mm, got -1 mm");
  EXPECT_EQ(p::kEdge.check(1e-5, "0.01 mm"), "expected an edge of at least 0.1 mm, got '0.01 mm'");
  EXPECT_EQ(p::kEdge.check(4e-3), std::nullopt);
  EXPECT_EQ(p::kFieldTolerance.check(1e-300), "expected a tolerance from 1e-12 to below 1, got 1e-300");
  EXPECT_EQ(p::kCliqueHops.check(5.0), "expected a clique size from 1 to 4 hops, got 5 hops");
  EXPECT_EQ(p::kAreaUnit.check(-1e-4), "expected an area unit above 0 cm^2, got -1 cm^2");
  EXPECT_EQ(p::kEdge.help_text(), "Target edge length, at least 0.1 mm (default 4 mm)");
  EXPECT_EQ(p::kFieldTolerance.help_text(false),
            "Stop when max UnShot <= tolerance * max force, from 1e-12 to below 1");
}

// Every kind of end (open, closed, none) has its words, and they say which values are in.
TEST(Parameters, EveryShapeOfRangeReadsAsItsBounds) {
  p::Parameter x{.name = "x",
                 .noun = "an x",
                 .kind = &pneuma::units::kind::length,
                 .display_unit = "cm",
                 .si_per_display_unit = 1e-2};
  const auto words = [&](double lo, bool lo_closed, double hi, bool hi_closed) {
    x.min = lo, x.min_closed = lo_closed, x.max = hi, x.max_closed = hi_closed;
    return x.expected();
  };
  EXPECT_EQ(words(0.01, true, 0.02, true), "an x from 1 to 2 cm");
  EXPECT_EQ(words(0.01, true, 0.02, false), "an x from 1 to below 2 cm");
  EXPECT_EQ(words(0.01, false, 0.02, true), "an x above 1 up to 2 cm");
  EXPECT_EQ(words(0.01, false, 0.02, false), "an x above 1 and below 2 cm");
  EXPECT_EQ(words(0.01, true, kInf, true), "an x of at least 1 cm");
  EXPECT_EQ(words(0.01, false, kInf, true), "an x above 1 cm");
  EXPECT_EQ(words(-kInf, true, 0.02, true), "an x of at most 2 cm");
  EXPECT_EQ(words(-kInf, true, 0.02, false), "an x below 2 cm");
  EXPECT_EQ(words(-kInf, true, kInf, true), "an x (any finite value)");
  // The words agree with accepts() at both ends.
  words(0.01, false, 0.02, true);
  EXPECT_FALSE(x.accepts(0.01));
  EXPECT_TRUE(x.accepts(0.02));
}
