#include "coordinator/admission.h"

#include <cmath>
#include <set>

#include "common/farm/content_hash.h"
#include "common/farm/farm_protocol.h"
#include "common/render/method_chooser.h"
#include "common/util/error.h"
#include "common/util/options.h"

namespace lightfarm {

void CheckSubmission(const JobRequest& req, const AdmissionLimits& limits,
                     const std::function<bool(const std::string& sha256)>& stored) {
  using Code = FarmError::Code;
  // Validate the manifest: every file uploaded, every path inside the scene directory.
  const SceneManifest& m = req.manifest;
  if (m.files.empty()) throw FarmError(Code::kInvalidArgument, "the scene manifest lists no files");
  if (m.files.size() > 100000) throw FarmError(Code::kResourceExhausted, "the scene manifest lists too many files");
  bool has_root = false;
  std::set<std::string> paths;
  for (const SceneFileRef& f : m.files) {
    if (!IsSafeScenePath(f.path))
      throw FarmError(Code::kInvalidArgument, "scene file path \"" + f.path.substr(0, 200) +
                                                  "\" must be relative and must not contain \"..\"");
    if (!paths.insert(f.path).second)
      throw FarmError(Code::kInvalidArgument, "scene file \"" + f.path + "\" is listed twice");
    if (!IsSha256Hex(f.sha256))
      throw FarmError(Code::kInvalidArgument, "scene file \"" + f.path + "\" has no valid SHA-256");
    if (!stored(f.sha256))
      throw FarmError(Code::kFailedPrecondition, "scene file \"" + f.path + "\" (blob " + f.sha256 +
                                                     ") was not uploaded");
    has_root |= f.path == m.root;
  }
  if (!has_root) throw FarmError(Code::kInvalidArgument, "the scene root \"" + m.root + "\" is not among its files");
  // Settings: malformed values are INVALID_ARGUMENT, configured limits RESOURCE_EXHAUSTED.
  const RenderSettings& s = req.settings;
  if (s.width < 0 || s.height < 0 || s.spp < 0)
    throw FarmError(Code::kInvalidArgument, "resolution and spp must not be negative");
  if (s.width > limits.max_resolution || s.height > limits.max_resolution)
    throw FarmError(Code::kResourceExhausted, "resolution " + std::to_string(s.width) + "x" + std::to_string(s.height) +
                                                  " exceeds this coordinator's limit of " +
                                                  std::to_string(limits.max_resolution) + " per axis");
  if (s.lights > limits.max_lights)
    throw FarmError(Code::kResourceExhausted, std::to_string(s.lights) + " lights exceed this coordinator's limit of " +
                                                  std::to_string(limits.max_lights));
  if (s.spp > limits.max_spp)
    throw FarmError(Code::kResourceExhausted, "spp " + std::to_string(s.spp) + " exceeds the limit of " +
                                                  std::to_string(limits.max_spp));
  if (!std::isfinite(s.progressive.until_noise) || s.progressive.until_noise < 0 || !std::isfinite(s.progressive.time_limit_s) ||
      s.progressive.time_limit_s < 0)
    throw FarmError(Code::kInvalidArgument, "until_noise and time_limit_s must be finite and not negative");
  if (s.progressive.passes > 1'000'000)
    throw FarmError(Code::kResourceExhausted, std::to_string(s.progressive.passes) + " passes exceed the limit of 1000000");
  if (s.method_rule.size() > 4096)
    throw FarmError(Code::kInvalidArgument, "method_rule is longer than 4096 bytes");
  try {
    CheckGatherMethodOptions(s.method, OptionMap::Parse(s.params));
  } catch (const OptionError& e) {
    throw FarmError(Code::kInvalidArgument, e.what());
  }
}

}  // namespace lightfarm
