// softshockd's HTTP side (docs/architecture.md, "The browser view"): the dashboard listener
// (--http-listen: the pages, their JSON API under /api/ and /metrics, all behind the daemon's
// bearer token) and the metrics listener (--metrics-listen: /metrics alone, without a token, for
// Prometheus on a bind address of the operator's choosing). Both are transport: the API calls the
// daemon's own gRPC services in-process, /metrics renders DaemonMetrics.
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

namespace softshock::server {

class DaemonMetrics;
class HttpListener;

struct HttpFrontendConfig {
  std::string http_listen;        // empty = no dashboard
  std::string metrics_listen;     // empty = no metrics listener
  std::string tls_cert, tls_key;  // the daemon's: the dashboard serves HTTPS with them
};

class HttpFrontend {
 public:
  HttpFrontend(HttpFrontendConfig config, DaemonMetrics& metrics);
  ~HttpFrontend();

  // Starts the configured listeners. `channel` reaches the daemon's gRPC services in-process
  // (grpc::Server::InProcessChannel). Throws std::runtime_error when one cannot listen.
  void start(std::shared_ptr<grpc::Channel> channel);
  // Stops both; requests in progress finish first.
  void stop();
  int dashboard_port() const;  // 0 = none
  int metrics_port() const;
  bool dashboard_tls() const { return !config_.tls_cert.empty(); }

 private:
  HttpFrontendConfig config_;
  DaemonMetrics& metrics_;
  std::unique_ptr<HttpListener> dashboard_, metrics_listener_;
};

}  // namespace softshock::server
