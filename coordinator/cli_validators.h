// CLI11 validators shared by lightfarm, lightfarm-coordinator and lightfarm-worker.
#pragma once

#include <CLI/CLI.hpp>

#include <cmath>
#include <string>

namespace lightfarm {

// CLI::Range for a floating-point option that also refuses NaN: CLI::Range tests
// `value < min || value > max`, which NaN passes (`--poll-interval nan` made the worker poll
// without ever sleeping, `--lease-timeout nan` an undefined lease length).
inline CLI::Validator FiniteRange(double min, double max) {
  CLI::Validator range = CLI::Range(min, max);
  return CLI::Validator(
      [range](std::string& value) {
        double v = 0;
        if (CLI::detail::lexical_cast(value, v) && std::isnan(v)) return std::string("Value nan is not a number");
        std::string copy = value;
        return range(copy);
      },
      range.get_description());
}

}  // namespace lightfarm
