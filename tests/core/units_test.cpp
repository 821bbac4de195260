#include "pneuma/core/units.h"

#include <gtest/gtest.h>

namespace u = pneuma::units;

TEST(Units, ClinicalQuantitiesConvertToSI) {
  // Oracles: the definitions 1 cmH2O = 98.0665 Pa, 1 L = 1e-3 m^3, 1 min = 60 s.
  EXPECT_DOUBLE_EQ(u::parse("0.1 L/cmH2O", u::kind::compliance), 0.1e-3 / 98.0665);
  EXPECT_DOUBLE_EQ(u::parse("2 cmH2O*s/L", u::kind::resistance), 2 * 98.0665 / 1e-3);
  EXPECT_DOUBLE_EQ(u::parse("12 /min", u::kind::rate), 0.2);
  EXPECT_DOUBLE_EQ(u::parse("500 mL", u::kind::volume), 5e-4);
  EXPECT_DOUBLE_EQ(u::parse("3 mm", u::kind::length), 3e-3);
  EXPECT_DOUBLE_EQ(u::parse("3mm", u::kind::length), 3e-3);
  EXPECT_DOUBLE_EQ(u::parse("1 cm^2", u::kind::area), 1e-4);
  EXPECT_DOUBLE_EQ(u::parse("30 L/min", u::kind::flow), 0.5e-3);
  EXPECT_DOUBLE_EQ(u::parse("3 kPa", u::kind::shear_modulus), 3000.0);
  EXPECT_DOUBLE_EQ(u::parse("100 Hz", u::kind::rate), 100.0);
  EXPECT_DOUBLE_EQ(u::parse("50 %", u::kind::fraction), 0.5);
  EXPECT_DOUBLE_EQ(u::parse("0.25", u::kind::fraction), 0.25);
  EXPECT_DOUBLE_EQ(u::parse("-1.5e-3 s", u::kind::duration), -1.5e-3);
}

TEST(Units, MissingOrWrongUnitIsAnErrorNamingTheKind) {
  try {
    u::parse("0.1", u::kind::compliance);
    FAIL() << "a compliance without unit was accepted";
  } catch (const u::UnitError& e) {
    EXPECT_STREQ(e.what(), "expected a compliance such as '0.1 L/cmH2O', got '0.1'");
  }
  EXPECT_THROW(u::parse("500 cmH2O", u::kind::volume), u::UnitError);    // wrong dimension
  EXPECT_THROW(u::parse("12 /fortnight", u::kind::rate), u::UnitError);  // unknown unit
  EXPECT_THROW(u::parse("ml 500", u::kind::volume), u::UnitError);
  EXPECT_THROW(u::parse("", u::kind::volume), u::UnitError);
  EXPECT_THROW(u::parse("nan mL", u::kind::volume), u::UnitError);
  EXPECT_THROW(u::parse("5 mL/", u::kind::volume), u::UnitError);
  EXPECT_THROW(u::parse("5 m^x", u::kind::length), u::UnitError);
  try {
    u::parse("3", u::kind::area);
  } catch (const u::UnitError& e) {
    EXPECT_STREQ(e.what(), "expected an area such as '1 cm^2', got '3'");
  }
}

TEST(Units, RatioParsesAsQuotient) {
  EXPECT_DOUBLE_EQ(u::parse_ratio("1:2"), 0.5);
  EXPECT_DOUBLE_EQ(u::parse_ratio(" 1 : 1.5 "), 1 / 1.5);
  EXPECT_THROW(u::parse_ratio("1/2"), u::UnitError);
  EXPECT_THROW(u::parse_ratio("0:2"), u::UnitError);
  EXPECT_THROW(u::parse_ratio("1:x"), u::UnitError);
}
