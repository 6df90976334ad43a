// The coordinator's HTTP side (`--http-listen`): the dashboard page at `/`, a JSON API under
// `/api/v1/`, Prometheus text at `/metrics`. Pages and API read the Coordinator directly (same
// process, no gRPC hop); the page's HTML, CSS and JS are compiled in (coordinator/web/), so it
// works on a machine with no internet.
//
// Auth: with a token, every request needs it, as `Authorization: Bearer <token>` or as the
// HttpOnly cookie that the /login form sets (it holds a hash of the token, never the token).
// State-changing requests (POST) also need the `X-Lightfarm-Request` header, which a cross-site
// form cannot send, so the cookie alone cannot be used by another site (CSRF).
#pragma once

#include <memory>
#include <string>
#include <thread>

namespace httplib {
class Server;
}

namespace lightfarm {

class Coordinator;

struct HttpConfig {
  std::string listen;     // HOST:PORT, or PORT alone for 127.0.0.1:PORT
  std::string token;      // empty: no auth (then only a loopback host is accepted...)
  bool allow_open = false;  // ...unless this is set: serve without a token on any host
  bool metrics_only = false;  // serve /metrics alone (`--metrics-listen`)
  std::string bench_dir;  // `lightfarm bench` output directories whose plots the page shows
};

class HttpServer {
 public:
  // Binds at once (throws with the address when it cannot); serves on its own thread.
  HttpServer(Coordinator& coordinator, HttpConfig config);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;
  int port() const { return port_; }
  void Stop();

 private:
  void Routes();
  Coordinator& c_;
  HttpConfig config_;
  std::string cookie_value_;  // the login cookie's value: a hash of the token
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  int port_ = 0;
};

// Escapes text for HTML element content and attribute values.
std::string HtmlEscape(const std::string& text);

}  // namespace lightfarm
