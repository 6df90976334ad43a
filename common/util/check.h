// Invariants, as pbrt-v4 states them: CHECK holds in every build (a broken invariant means a
// wrong image or memory corruption ahead, so the process stops at once with file:line and the
// values compared); DCHECK only in debug builds, for the hot paths where a per-element test
// would cost measurable time. Neither is for input a user or a client can get wrong: that is an
// exception with a message (SceneError, OptionError, FarmError).
#pragma once

#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>

namespace lightfarm::detail {

[[noreturn]] inline void CheckFailed(const char* file, int line, const std::string& what) {
  std::fprintf(stderr, "%s:%d: CHECK failed: %s\n", file, line, what.c_str());
  std::fflush(stderr);
  std::abort();
}

template <typename A, typename B>
std::string CheckValues(const char* expr, const A& a, const B& b) {
  std::ostringstream s;
  s << expr << " (" << a << " vs " << b << ")";
  return s.str();
}

}  // namespace lightfarm::detail

#define CHECK(cond) \
  ((cond) ? (void)0 : ::lightfarm::detail::CheckFailed(__FILE__, __LINE__, #cond))

#define LIGHTFARM_CHECK_OP(a, b, op)                                                              \
  do {                                                                                            \
    const auto& check_a_ = (a);                                                                   \
    const auto& check_b_ = (b);                                                                   \
    if (!(check_a_ op check_b_))                                                                  \
      ::lightfarm::detail::CheckFailed(__FILE__, __LINE__,                                        \
                                       ::lightfarm::detail::CheckValues(#a " " #op " " #b, check_a_, check_b_)); \
  } while (false)

#define CHECK_EQ(a, b) LIGHTFARM_CHECK_OP(a, b, ==)
#define CHECK_NE(a, b) LIGHTFARM_CHECK_OP(a, b, !=)
#define CHECK_LT(a, b) LIGHTFARM_CHECK_OP(a, b, <)
#define CHECK_LE(a, b) LIGHTFARM_CHECK_OP(a, b, <=)
#define CHECK_GT(a, b) LIGHTFARM_CHECK_OP(a, b, >)
#define CHECK_GE(a, b) LIGHTFARM_CHECK_OP(a, b, >=)

#ifdef NDEBUG
// Not evaluated in release builds (the arguments may be expensive), but still compiled.
#define DCHECK(cond) ((void)sizeof(!(cond)))
#define DCHECK_EQ(a, b) ((void)sizeof((a) == (b)))
#define DCHECK_LT(a, b) ((void)sizeof((a) < (b)))
#define DCHECK_LE(a, b) ((void)sizeof((a) <= (b)))
#else
#define DCHECK(cond) CHECK(cond)
#define DCHECK_EQ(a, b) CHECK_EQ(a, b)
#define DCHECK_LT(a, b) CHECK_LT(a, b)
#define DCHECK_LE(a, b) CHECK_LE(a, b)
#endif
