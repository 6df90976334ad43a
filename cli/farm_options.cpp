#include "cli/farm_options.h"

#include <cstdio>
#include <filesystem>

#include "common/farm/program.h"
#include "common/farm/proto_convert.h"
#include "common/image/image_io.h"
#include "common/util/error.h"
#include "common/util/file.h"

namespace lightfarm::cli {

namespace fs = std::filesystem;

void AddServerOptions(CLI::App* cmd, ServerArgs& a) {
  cmd->add_option("--server", a.server, "Coordinator HOST:PORT")
      ->required()
      ->check(HostPort(false));
  cmd->add_option("--token-file", a.token_file, "File holding the bearer token");
  cmd->add_flag("--tls", a.tls, "Connect with TLS");
  cmd->add_option("--tls-ca", a.tls_ca, "PEM root certificates for TLS (default: system)");
  cmd->add_option("--timeout", a.timeout, "Seconds allowed for each request")->check(FiniteRange(0.001, 1e6));
}

std::unique_ptr<RenderClient> ConnectToCoordinator(const ServerArgs& a) {
  ChannelOptions o;
  o.address = a.server;
  o.tls = a.tls || !a.tls_ca.empty();
  o.tls_ca = a.tls_ca;
  return std::make_unique<RenderClient>(MakeChannel(o), ReadTokenFile(a.token_file), a.timeout);
}

void WriteFetchedResult(const std::string& exr_path, const std::string& exr_bytes,
                        const std::string& stats_json, const std::string& stats_path) {
  if (exr_path.size() < 5 || exr_path.substr(exr_path.size() - 4) != ".exr")
    throw OptionError("--out must name an .exr file, got \"" + exr_path + "\"");
  fs::path out(exr_path);
  if (out.has_parent_path()) fs::create_directories(out.parent_path());
  WriteFileAtomically(exr_path, exr_bytes);
  const std::string stem = exr_path.substr(0, exr_path.size() - 4);
  WritePNG(stem + ".png", ReadImage(exr_path));
  WriteFileAtomically(stats_path.empty() ? stem + ".json" : stats_path, stats_json + "\n");
}

std::string ProgressPhase(const v1::JobStatus& st) {
  if (!st.progressive()) return st.stage_name();
  return "pass " + std::to_string(st.passes_done() + 1) + "/" + std::to_string(st.passes_total()) + " " +
         st.stage_name();
}

std::string DescribeJob(const v1::JobStatus& st) {
  char buf[512];
  std::string s = "job " + st.job_id() + ": " + JobStateName(st.state());
  if (st.progressive()) {
    const bool running = st.state() == v1::JOB_STATE_RUNNING || st.state() == v1::JOB_STATE_PLANNING;
    std::snprintf(buf, sizeof(buf), ", %s %u/%u", running ? "pass" : "passes", st.passes_done() + (running ? 1 : 0),
                  st.passes_total());
    s += buf;
    if (st.noise_rel_stderr() >= 0) {
      std::snprintf(buf, sizeof(buf), ", noise %.4f (p90 pixel %.4f)", st.noise_rel_stderr(),
                    st.noise_p90_rel_stderr());
      s += buf;
    }
  }
  if (st.state() == v1::JOB_STATE_RUNNING) {
    std::snprintf(buf, sizeof(buf), ", stage %d/%d (%s), %llu/%llu tasks", st.stage() + 1,
                  st.stage_count(), st.stage_name().c_str(), (unsigned long long)st.tasks_done(),
                  (unsigned long long)st.tasks_total());
    s += buf;
    if (st.eta_s() >= 0) {
      std::snprintf(buf, sizeof(buf), ", eta %.1fs", st.eta_s());
      s += buf;
    }
  }
  if (!st.error().empty() && st.state() != v1::JOB_STATE_CANCELLED) s += " (" + st.error() + ")";
  return s;
}

}  // namespace lightfarm::cli
