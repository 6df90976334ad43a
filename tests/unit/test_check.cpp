// CHECK stops the process with file:line and the values compared, in every build; DCHECK costs
// nothing in a release build (its argument is not evaluated) and is a CHECK in a debug build.
#include <gtest/gtest.h>

#include "common/util/check.h"

namespace lightfarm {
namespace test_check {

int Counted(int* calls, int value) {
  ++*calls;
  return value;
}

TEST(CheckDeathTest, ABrokenInvariantStopsWithWhereAndTheValues) {
  const int rows = 3;
  EXPECT_DEATH(CHECK_LT(rows + 2, rows), "test_check.cpp:[0-9]+: CHECK failed: rows \\+ 2 < rows \\(5 vs 3\\)");
  EXPECT_DEATH(CHECK(rows == 4), "CHECK failed: rows == 4");
  CHECK_EQ(rows, 3);  // holds: nothing happens
  CHECK(rows > 0);
}

TEST(CheckDeathTest, DcheckIsFreeInReleaseAndACheckInDebug) {
  int calls = 0;
#ifdef NDEBUG
  DCHECK_LT(Counted(&calls, 7), 3);
  DCHECK(Counted(&calls, 0) == 1);
  EXPECT_EQ(calls, 0);
#else
  EXPECT_DEATH(DCHECK_LT(Counted(&calls, 7), 3), "CHECK failed");
  DCHECK_LT(Counted(&calls, 1), 3);
  EXPECT_EQ(calls, 1);
#endif
}

}  // namespace test_check
}  // namespace lightfarm
