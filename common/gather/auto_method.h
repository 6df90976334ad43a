// `--method auto` (the default, DESIGN.md: "picks by scene and accuracy target"): resolved to a
// registered method at plan time from the scene's Effects, the number of lights and, when given,
// `--param target_error=E` (relative L2 error against brute force with the same lights). The
// rule and the measurements behind it are in auto_method.cpp and docs/rendering.md.
#pragma once

#include <cstddef>
#include <string>

#include "common/scene/effects.h"
#include "common/util/options.h"

namespace lightfarm {

inline constexpr const char* kAutoMethod = "auto";

struct AutoMethodChoice {
  std::string method;  // a name the registry knows
  std::string rule;    // the row of the rule table that decided, for logs and stats
};

// Reads (and marks used) `target_error`; throws OptionError for a value that is not a number in
// (0, 1]. Deterministic: the coordinator and every worker resolve a job to the same method.
AutoMethodChoice ResolveAutoMethod(const Effects& effects, size_t lights, const OptionMap& params);

// `requested` itself unless it is "auto".
std::string ResolveGatherMethodName(const std::string& requested, const Effects& effects,
                                    size_t lights, const OptionMap& params);

// What can be checked before the scene is known (submit time, or before parsing): a concrete
// method is created with its parameters; "auto" checks target_error. Throws OptionError.
void CheckGatherMethodOptions(const std::string& name, const OptionMap& params);

}  // namespace lightfarm
