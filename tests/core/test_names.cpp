// The name tables every solver family declares beside its enums: each name
// parses back to its value, other text parses to nothing, and the lists the
// CLI and messages show hold every name once.

#include "photorig/solvers/core/names.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

namespace photorig::solvers::core {
namespace {

enum class Shape { kDisc, kSquare, kTriangle };
constexpr NameTable<Shape, 3> kShapeNames = {
    {{Shape::kDisc, "disc"}, {Shape::kSquare, "square"}, {Shape::kTriangle, "triangle"}}};
// Constant expressions: tables can be checked when they are compiled.
static_assert(ParseName(kShapeNames, "triangle") == Shape::kTriangle);
static_assert(!ParseName(kShapeNames, "circle").has_value());

TEST(NameTable, EveryNameParsesBackToItsValueAndNothingElseParses) {
  for (const NamedValue<Shape>& entry : kShapeNames) {
    EXPECT_EQ(ParseName(kShapeNames, entry.name), entry.value) << entry.name;
    EXPECT_STREQ(NameOf(kShapeNames, entry.value), entry.name);
  }
  EXPECT_FALSE(ParseName(kShapeNames, "Disc"));  // exact: no case folding
  EXPECT_FALSE(ParseName(kShapeNames, "disc "));
  EXPECT_FALSE(ParseName(kShapeNames, ""));
  EXPECT_STREQ(NameOf(kShapeNames, static_cast<Shape>(7)), "unknown");
}

TEST(NameTable, ListsHoldEveryNameOnceInTableOrder) {
  EXPECT_EQ(JoinNames(kShapeNames), "disc | square | triangle");
  EXPECT_EQ(JoinNames(kShapeNames, ", "), "disc, square, triangle");
  EXPECT_EQ(NamesInProse(kShapeNames), "disc, square or triangle");
  const auto map = NameMap(kShapeNames);
  ASSERT_EQ(map.size(), 3u);
  EXPECT_EQ(map.at("square"), Shape::kSquare);
}

}  // namespace
}  // namespace photorig::solvers::core
