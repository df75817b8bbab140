// One HTTP(S) listening address of softshockd (cpp-httplib, Debian's libcpp-httplib): the
// dashboard's (--http-listen) or the metrics' (--metrics-listen). What every listener does the
// same way lives here: binding "host:port" (port 0: the OS picks), TLS with the daemon's
// certificate, a fixed pool of handler threads with a bounded backlog of accepted connections
// (the accept loop waits when it is full, so a flood of connections queues in the kernel, not
// in the daemon), read/write timeouts and a request size bound, security headers, errors as
// JSON, and a metric per request by route (never by the raw path). Nothing here logs a request
// header: the bearer token never reaches the log.
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <thread>

namespace httplib {
class Server;
struct Request;
struct Response;
}  // namespace httplib

namespace softshock::server {

class DaemonMetrics;

struct HttpListenerOptions {
  std::string name;     // "dashboard" or "metrics": the metrics' listener label and the log's
  std::string address;  // "127.0.0.1:8080", "[::1]:0", "0.0.0.0:9464"
  std::string tls_cert_file, tls_key_file;  // both or neither: serve HTTPS
  int threads = 16;                         // requests served at once
  std::size_t max_pending = 256;            // accepted connections waiting for a thread
  std::size_t max_request_bytes = 64 * 1024;
  std::chrono::seconds io_timeout{10};
  std::chrono::seconds keep_alive{5};
  // Extra headers on every answer (the dashboard's Content-Security-Policy).
  std::vector<std::pair<std::string, std::string>> headers;
};

// "host:port" or "[v6]:port" into host and port; throws std::invalid_argument.
void split_http_address(const std::string& address, std::string* host, int* port);

// `s` as a JSON string literal, quotes included.
std::string json_quote(const std::string& s);

// An HTTP error answer: {"error": {"code": "NOT_FOUND", "message": "..."}}.
std::string error_json(const std::string& code, const std::string& message);
void set_error(httplib::Response& res, int status, const std::string& code,
               const std::string& message);

class HttpListener {
 public:
  using Handler = std::function<void(const httplib::Request&, httplib::Response&)>;

  // `metrics` may be null (no request metrics).
  HttpListener(HttpListenerOptions options, DaemonMetrics* metrics);
  ~HttpListener();
  HttpListener(const HttpListener&) = delete;
  HttpListener& operator=(const HttpListener&) = delete;

  // Routes, before start(). `route` names the pattern in metrics ("/api/jobs/{id}").
  void get(const std::string& route, const std::string& pattern, Handler handler);
  void post(const std::string& route, const std::string& pattern, Handler handler);

  // Binds and serves on a thread of its own; returns the bound port. Throws std::runtime_error
  // (cannot bind, unreadable TLS files).
  int start();
  // Stops accepting, lets the requests in progress finish, joins the threads.
  void stop();
  int port() const { return port_; }
  const std::string& name() const { return options_.name; }
  bool tls() const { return !options_.tls_cert_file.empty(); }

 private:
  Handler timed(const std::string& route, Handler handler);

  HttpListenerOptions options_;
  DaemonMetrics* metrics_;
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  int port_ = 0;
};

}  // namespace softshock::server
