#include "coordinator/dashboard.h"

#include <httplib.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "common/util/bench_table.h"
#include "common/farm/content_hash.h"
#include "common/farm/proto_convert.h"
#include "common/farm/rpc.h"
#include "common/image/image_io.h"
#include "common/util/file.h"
#include "coordinator/coordinator.h"
#include "coordinator/web/dashboard_assets.h"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace lightfarm {

std::string HtmlEscape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char ch : text) {
    switch (ch) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += ch;
    }
  }
  return out;
}

namespace {

constexpr const char* kCookie = "lightfarm_session";

json JobJson(const JobSnapshot& st) {
  json j = {{"id", st.job_id},
            {"name", st.name},
            {"scene", st.scene},
            {"scene_sha256", st.scene_sha256},
            {"state", JobStateName(st.state)},
            {"method", st.method},
            {"priority", st.priority},
            {"stage", st.stage},
            {"stage_count", st.stage_count},
            {"stage_name", st.stage_name},
            {"tasks_done", st.tasks_done},
            {"tasks_total", st.tasks_total},
            {"elapsed_s", st.elapsed_s},
            {"eta_s", st.eta_s},
            {"attempts", st.attempts},
            {"tasks_completed_total", st.tasks_completed_total},
            {"error", st.error},
            {"waiting", st.waiting},
            {"tasks_verified", st.tasks_verified},
            {"progressive", st.progressive}};
  if (st.progressive) {
    j["passes_done"] = st.passes_done;
    j["passes_total"] = st.passes_total;
    j["noise_rel_stderr"] = st.noise_rel_stderr;
    j["noise_p90_rel_stderr"] = st.noise_p90_rel_stderr;
  }
  return j;
}

json WorkerJson(const WorkerSnapshot& w) {
  return {{"id", w.worker_id},
          {"name", w.name},
          {"version", w.version},
          {"threads", w.threads},
          {"lease_id", w.lease_id},
          {"job_id", w.job_id},
          {"last_seen_s", w.last_seen_s},
          {"alive", w.alive},
          {"tasks_done", w.tasks_done},
          {"tasks_failed", w.tasks_failed},
          {"blocked_jobs", w.blocked_jobs},
          {"blocklisted", w.blocklisted}};
}

int HttpStatusOf(FarmError::Code code) {
  switch (code) {
    case FarmError::Code::kInvalidArgument: return 400;
    case FarmError::Code::kNotFound: return 404;
    case FarmError::Code::kResourceExhausted: return 429;
    case FarmError::Code::kFailedPrecondition: return 409;
    case FarmError::Code::kUnavailable: return 503;
    case FarmError::Code::kDataLoss: return 500;
  }
  return 500;
}

// Job names and errors are whatever clients sent: invalid UTF-8 is replaced, never thrown on.
void SendJson(httplib::Response& res, const json& j) {
  res.set_content(j.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}

void SendError(httplib::Response& res, int status, const std::string& message) {
  res.status = status;
  SendJson(res, json{{"error", message}});
}

// Runs a handler, turning what it throws into a JSON error with the matching HTTP status; the
// coordinator survives every request, as on the gRPC side.
template <typename Fn>
void Guarded(httplib::Response& res, Fn&& fn) {
  try {
    fn();
  } catch (const FarmError& e) {
    SendError(res, HttpStatusOf(e.code()), e.what());
  } catch (const std::exception& e) {
    spdlog::error("http: internal error: {}", e.what());
    SendError(res, 500, e.what());
  }
}

bool IsLoopbackHost(const std::string& host) {
  return host == "127.0.0.1" || host == "localhost" || host == "::1" || host == "[::1]";
}

std::string CookieFrom(const httplib::Request& req, const std::string& name) {
  const std::string header = req.get_header_value("Cookie");
  size_t pos = 0;
  while (pos < header.size()) {
    size_t end = header.find(';', pos);
    if (end == std::string::npos) end = header.size();
    std::string part = header.substr(pos, end - pos);
    part.erase(0, part.find_first_not_of(' '));
    if (part.compare(0, name.size() + 1, name + "=") == 0) return part.substr(name.size() + 1);
    pos = end + 1;
  }
  return "";
}

// The bench results under `dir` (each `lightfarm bench --out-dir` directory holds a
// results.csv): per scene (named by its directory and file), its content hash when the
// coordinator can read the file (a job's page links to the plot of its own scene by it) and the
// rows' time and errors for the error-versus-time plot.
json BenchJson(const std::string& dir) {
  json scenes = json::object();
  if (dir.empty() || !fs::is_directory(dir)) return scenes;
  std::vector<fs::path> files;
  for (const auto& entry : fs::recursive_directory_iterator(dir))
    if (entry.is_regular_file() && entry.path().filename() == "results.csv") files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  for (const fs::path& file : files) {
    std::vector<BenchRow> rows;
    try {
      rows = ReadBenchCsv(file.string());
    } catch (const std::exception& e) {
      spdlog::warn("http: bench results {}: {}", file.string(), e.what());
      continue;
    }
    for (const BenchRow& r : rows) {
      const fs::path path(r.scene);
      const std::string key = (path.parent_path().filename() / path.filename()).generic_string();
      json& scene = scenes[key];
      if (!scene.contains("sha256")) {
        std::string sha;
        try {
          if (fs::is_regular_file(path)) sha = Sha256OfFile(path.string());
        } catch (const std::exception&) {
        }
        scene["sha256"] = sha;
        scene["rows"] = json::array();
      }
      const auto num = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
      scene["rows"].push_back({{"method", r.method},
                               {"setting", r.setting},
                               {"lights", r.lights},
                               {"time_s", num(r.time_total_s)},
                               {"rel_l1", num(r.rel_l1)},
                               {"truth_rel_l1", num(r.truth_rel_l1)},
                               {"source", fs::relative(file, dir).string()}});
    }
  }
  return scenes;
}

}  // namespace

HttpServer::HttpServer(Coordinator& coordinator, HttpConfig config)
    : c_(coordinator), config_(std::move(config)), server_(std::make_unique<httplib::Server>()) {
  std::string host = "127.0.0.1";
  std::string port_text = config_.listen;
  if (const size_t colon = config_.listen.rfind(':'); colon != std::string::npos) {
    host = config_.listen.substr(0, colon);
    port_text = config_.listen.substr(colon + 1);
  }
  if (host.size() > 1 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  int port = -1;
  try {
    size_t used = 0;
    port = std::stoi(port_text, &used);
    if (used != port_text.size()) port = -1;
  } catch (const std::exception&) {
  }
  if (port < 0 || port > 65535) throw std::invalid_argument("HTTP listen address \"" + config_.listen + "\": expected [HOST:]PORT");
  if (!config_.metrics_only && config_.token.empty() && !config_.allow_open && !IsLoopbackHost(host))
    throw std::invalid_argument("--http-listen " + config_.listen +
                                ": the dashboard can cancel jobs; without --token-file it serves loopback only "
                                "(use 127.0.0.1, add --token-file, or pass --http-allow-open)");
  if (!config_.token.empty()) cookie_value_ = Sha256Hex("lightfarm-dashboard-session\n" + config_.token);
  Routes();
  if (port == 0) {
    port_ = server_->bind_to_any_port(host);
    if (port_ <= 0) throw std::runtime_error("cannot listen on " + config_.listen);
  } else {
    if (!server_->bind_to_port(host, port)) throw std::runtime_error("cannot listen on " + config_.listen);
    port_ = port;
  }
  thread_ = std::thread([this] { server_->listen_after_bind(); });
}

HttpServer::~HttpServer() { Stop(); }

void HttpServer::Stop() {
  if (!server_) return;
  server_->stop();
  if (thread_.joinable()) thread_.join();
  server_.reset();
}

void HttpServer::Routes() {
  httplib::Server& s = *server_;
  s.set_default_headers({{"X-Content-Type-Options", "nosniff"},
                         {"X-Frame-Options", "DENY"},
                         {"Referrer-Policy", "no-referrer"},
                         {"Cache-Control", "no-store"}});

  s.Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
    res.set_content(c_.MetricsText(), "text/plain; version=0.0.4");
  });
  if (config_.metrics_only) return;

  // Auth first: the login form is the only thing served without the token.
  s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (config_.token.empty() || req.path == "/login" || req.path == "/static/style.css")
      return httplib::Server::HandlerResponse::Unhandled;
    const bool bearer = TokenMatches(config_.token, req.get_header_value("Authorization"));
    const std::string cookie = CookieFrom(req, kCookie);
    const bool session = !cookie.empty() && TokenMatches(cookie_value_, "Bearer " + cookie);
    if (bearer || session) return httplib::Server::HandlerResponse::Unhandled;
    if (req.method == "GET" && req.path.rfind("/api/", 0) != 0 && req.path != "/metrics") {
      res.status = 303;
      res.set_header("Location", "/login");
      return httplib::Server::HandlerResponse::Handled;
    }
    res.set_header("WWW-Authenticate", "Bearer");
    SendError(res, 401, "missing or wrong bearer token (Authorization header or the /login cookie)");
    return httplib::Server::HandlerResponse::Handled;
  });

  // --- pages: one shell; the script renders the view its path names ----------------------------
  const auto page = [](const httplib::Request&, httplib::Response& res) {
    res.set_header("Content-Security-Policy",
                   "default-src 'self'; img-src 'self' data: blob:; style-src 'self'; script-src 'self'; "
                   "frame-ancestors 'none'");
    res.set_content(web::kIndexHtml, "text/html; charset=utf-8");
  };
  s.Get("/", page);
  s.Get("/workers", page);
  s.Get("/bench", page);
  s.Get(R"(/jobs/(\d+))", page);
  s.Get("/static/app.js", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(web::kAppJs, "text/javascript; charset=utf-8");
  });
  s.Get("/static/style.css", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(web::kStyleCss, "text/css; charset=utf-8");
  });

  s.Get("/login", [this](const httplib::Request& req, httplib::Response& res) {
    std::string html = web::kLoginHtml;
    const std::string marker = "<!--message-->";
    if (req.has_param("error")) {
      // The query string is shown back escaped: `?error=<script>` is text.
      html.replace(html.find(marker), marker.size(),
                   "<p class=\"error\">" + HtmlEscape(req.get_param_value("error")) + "</p>");
    } else if (config_.token.empty()) {
      html.replace(html.find(marker), marker.size(), "<p>This coordinator has no token: nothing to log in to.</p>");
    }
    res.set_content(html, "text/html; charset=utf-8");
  });
  s.Post("/login", [this](const httplib::Request& req, httplib::Response& res) {
    const std::string token = req.has_param("token") ? req.get_param_value("token") : "";
    res.status = 303;
    if (config_.token.empty() || !TokenMatches(config_.token, "Bearer " + token)) {
      res.set_header("Location", "/login?error=wrong+token");
      return;
    }
    res.set_header("Set-Cookie", std::string(kCookie) + "=" + cookie_value_ +
                                     "; Path=/; HttpOnly; SameSite=Strict");
    res.set_header("Location", "/");
  });
  s.Post("/logout", [](const httplib::Request&, httplib::Response& res) {
    res.set_header("Set-Cookie", std::string(kCookie) + "=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0");
    res.status = 303;
    res.set_header("Location", "/login");
  });

  // --- JSON API ---------------------------------------------------------------------------------
  s.Get("/api/v1/jobs", [this](const httplib::Request&, httplib::Response& res) {
    Guarded(res, [&] {
      json jobs = json::array();
      const std::vector<JobSnapshot> all = c_.ListJobs();
      for (auto it = all.rbegin(); it != all.rend(); ++it) jobs.push_back(JobJson(*it));  // newest first
      SendJson(res, json{{"jobs", jobs}});
    });
  });
  s.Get(R"(/api/v1/jobs/(\d+))", [this](const httplib::Request& req, httplib::Response& res) {
    Guarded(res, [&] {
      const JobSnapshot st = c_.GetJob(req.matches[1]);
      json j = JobJson(st);
      j["stats"] = nullptr;
      const bool partial = st.progressive && st.passes_done > 0;
      if (st.state == JobState::kDone || partial) {
        try {
          j["stats"] = json::parse(c_.GetResult(st.job_id).stats_json);
          j["has_result"] = true;
        } catch (const std::exception&) {
          j["has_result"] = false;
        }
      }
      SendJson(res, j);
    });
  });
  s.Get(R"(/api/v1/jobs/(\d+)/preview\.png)", [this](const httplib::Request& req, httplib::Response& res) {
    Guarded(res, [&] {
      JobPreview preview;
      if (!c_.Preview(req.matches[1], 0, &preview)) {
        SendError(res, 404, "no preview: the job is not rendering its final stage");
        return;
      }
      res.set_header("X-Preview-Version", std::to_string(preview.tiles));
      res.set_content(preview.png, "image/png");
    });
  });
  s.Get(R"(/api/v1/jobs/(\d+)/image\.png)", [this](const httplib::Request& req, httplib::Response& res) {
    Guarded(res, [&] {
      const JobResult result = c_.GetResult(req.matches[1]);
      // Tone-mapped once per result blob; later requests read the file.
      const fs::path dir = fs::path(c_.options().state_dir) / "dashboard";
      const fs::path png = dir / (fs::path(result.exr_path).filename().string() + ".png");
      if (!fs::exists(png)) {
        fs::create_directories(dir);
        WritePNG(png.string(), ReadImage(result.exr_path));  // atomic: concurrent requests each rename a whole file
      }
      res.set_content(ReadFile(png.string()), "image/png");
    });
  });
  s.Get(R"(/api/v1/jobs/(\d+)/result\.exr)", [this](const httplib::Request& req, httplib::Response& res) {
    Guarded(res, [&] {
      const JobResult result = c_.GetResult(req.matches[1]);
      res.set_header("Content-Disposition",
                     "attachment; filename=\"lightfarm-job-" + std::string(req.matches[1]) + ".exr\"");
      // Streamed from the blob store: a result can be gigabytes.
      auto file = std::make_shared<std::ifstream>(result.exr_path, std::ios::binary);
      if (!*file) throw FarmError(FarmError::Code::kNotFound, "cannot read the result of job " + std::string(req.matches[1]));
      res.set_content_provider(size_t(fs::file_size(result.exr_path)), "image/x-exr",
                               [file](size_t offset, size_t length, httplib::DataSink& sink) {
                                 std::string chunk(std::min<size_t>(length, 1 << 20), '\0');
                                 file->seekg(std::streamoff(offset));
                                 file->read(chunk.data(), std::streamsize(chunk.size()));
                                 if (file->gcount() <= 0) return false;
                                 sink.write(chunk.data(), size_t(file->gcount()));
                                 return true;
                               });
    });
  });
  const auto require_intent = [](const httplib::Request& req, httplib::Response& res) {
    if (req.get_header_value("X-Lightfarm-Request").empty()) {
      SendError(res, 403, "POST requests need the X-Lightfarm-Request header");
      return false;
    }
    return true;
  };
  s.Post(R"(/api/v1/jobs/(\d+)/cancel)", [this, require_intent](const httplib::Request& req, httplib::Response& res) {
    if (!require_intent(req, res)) return;
    Guarded(res, [&] { SendJson(res, JobJson(c_.Cancel(req.matches[1]))); });
  });
  s.Post(R"(/api/v1/jobs/(\d+)/delete)", [this, require_intent](const httplib::Request& req, httplib::Response& res) {
    if (!require_intent(req, res)) return;
    Guarded(res, [&] {
      c_.Delete(req.matches[1]);
      SendJson(res, json{{"id", std::string(req.matches[1])}, {"deleted", true}});
    });
  });
  s.Post(R"(/api/v1/jobs/(\d+)/priority)", [this, require_intent](const httplib::Request& req, httplib::Response& res) {
    if (!require_intent(req, res)) return;
    Guarded(res, [&] {
      const json body = json::parse(req.body, nullptr, false);
      if (body.is_discarded() || !body.is_object() || !body.contains("priority") ||
          !body["priority"].is_number_integer())
        throw FarmError(FarmError::Code::kInvalidArgument, "expected a JSON body {\"priority\": <integer>}");
      const int64_t p = body["priority"].get<int64_t>();
      if (p < INT32_MIN || p > INT32_MAX)
        throw FarmError(FarmError::Code::kInvalidArgument, "priority out of range");
      SendJson(res, JobJson(c_.SetPriority(req.matches[1], int(p))));
    });
  });
  s.Get("/api/v1/workers", [this](const httplib::Request&, httplib::Response& res) {
    Guarded(res, [&] {
      json workers = json::array();
      for (const WorkerSnapshot& w : c_.ListWorkers()) workers.push_back(WorkerJson(w));
      SendJson(res, json{{"workers", workers}});
    });
  });
  s.Get("/api/v1/bench", [this](const httplib::Request&, httplib::Response& res) {
    Guarded(res, [&] { SendJson(res, json{{"scenes", BenchJson(config_.bench_dir)}}); });
  });
  s.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (res.body.empty()) SendError(res, res.status, res.status == 404 ? "not found" : "error");
  });
}

}  // namespace lightfarm
