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

const char* JobStateName(JobState state) {
  switch (state) {
    case JobState::kQueued: return "queued";
    case JobState::kPlanning: return "planning";
    case JobState::kRunning: return "running";
    case JobState::kDone: return "done";
    case JobState::kFailed: return "failed";
    case JobState::kCancelled: return "cancelled";
  }
  return "unknown";
}

v1::JobState ToProto(JobState state) { return v1::JobState(int(state)); }

JobState FromProto(v1::JobState state) {
  return state == v1::JOB_STATE_UNSPECIFIED ? JobState::kQueued : JobState(int(state));
}

v1::SceneManifest ToProto(const SceneManifest& m) {
  v1::SceneManifest p;
  p.set_root(m.root);
  for (const SceneFileRef& f : m.files) {
    v1::SceneFile* file = p.add_files();
    file->set_path(f.path);
    file->set_sha256(f.sha256);
  }
  return p;
}

SceneManifest FromProto(const v1::SceneManifest& p) {
  SceneManifest m;
  m.root = p.root();
  m.files.reserve(size_t(p.files_size()));
  for (const v1::SceneFile& f : p.files()) m.files.push_back({f.path(), f.sha256()});
  return m;
}

std::string EncodeManifest(const SceneManifest& m) { return ToProto(m).SerializeAsString(); }

SceneManifest DecodeManifest(const std::string& bytes) {
  v1::SceneManifest p;
  p.ParseFromString(bytes);
  return FromProto(p);
}

std::string EncodeSettings(const RenderSettings& s) { return ToProto(s).SerializeAsString(); }

RenderSettings DecodeSettings(const std::string& bytes) {
  v1::RenderSettings p;
  p.ParseFromString(bytes);
  return FromProto(p);
}

const char* JobStateName(v1::JobState state) {
  return state >= v1::JOB_STATE_QUEUED && state <= v1::JOB_STATE_CANCELLED ? JobStateName(FromProto(state))
                                                                            : "unknown";
}

bool IsTerminal(v1::JobState state) {
  return state >= v1::JOB_STATE_QUEUED && state <= v1::JOB_STATE_CANCELLED && IsTerminal(FromProto(state));
}

}  // namespace lightfarm
