#include "common/farm/proto_convert.h"

namespace lightfarm {

v1::RenderSettings ToProto(const RenderSettings& s) {
  v1::RenderSettings p;
  p.set_method(s.method);
  p.set_width(s.width);
  p.set_height(s.height);
  p.set_filter(s.filter);
  p.set_spp(s.spp);
  p.set_lights(s.lights);
  p.set_seed(s.seed);
  for (const std::string& kv : s.params) p.add_params(kv);
  p.set_method_rule(s.method_rule);
  p.set_verify(s.verify);
  if (s.progressive.progressive()) {
    p.set_passes(s.progressive.passes);
    p.set_until_noise(s.progressive.until_noise);
    p.set_time_limit_s(s.progressive.time_limit_s);
  }
  return p;
}

RenderSettings FromProto(const v1::RenderSettings& p) {
  RenderSettings s;
  s.method = p.method().empty() ? "brute" : p.method();
  s.width = p.width();
  s.height = p.height();
  s.filter = p.filter();
  s.spp = p.spp();  // 0: the method's default
  s.lights = p.lights() == 0 ? kDefaultLights : size_t(p.lights());
  s.seed = p.seed();
  s.params.assign(p.params().begin(), p.params().end());
  s.method_rule = p.method_rule();
  s.verify = p.verify();
  s.progressive.until_noise = p.until_noise();
  s.progressive.time_limit_s = p.time_limit_s();
  s.progressive.passes = PassPlan::PassesFor(p.passes(), s.progressive);
  return s;
}

const char* JobStateName(v1::JobState state) {
  switch (state) {
    case v1::JOB_STATE_QUEUED: return "queued";
    case v1::JOB_STATE_PLANNING: return "planning";
    case v1::JOB_STATE_RUNNING: return "running";
    case v1::JOB_STATE_DONE: return "done";
    case v1::JOB_STATE_FAILED: return "failed";
    case v1::JOB_STATE_CANCELLED: return "cancelled";
    default: return "unknown";
  }
}

bool IsTerminal(v1::JobState state) {
  return state == v1::JOB_STATE_DONE || state == v1::JOB_STATE_FAILED ||
         state == v1::JOB_STATE_CANCELLED;
}

}  // namespace lightfarm
