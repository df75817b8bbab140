#include "server/http/http_frontend.hpp"

#include <httplib.h>

#include "server/http/dashboard_api.hpp"
#include "server/http/grpc_bridge.hpp"
#include "server/http/http_listener.hpp"
#include "server/http/static_assets.hpp"
#include "server/metrics/daemon_metrics.hpp"
#include "softshock/v1/service.grpc.pb.h"

namespace softshock::server {

namespace {

// The pages load only the daemon's own scripts and styles and talk only to it.
constexpr const char* kContentSecurityPolicy =
    "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
    "connect-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'";

void answer_metrics(const DaemonMetrics& metrics, httplib::Response& res) {
  res.status = 200;
  res.set_header("Cache-Control", "no-store");
  res.set_content(metrics.render(), metrics::Registry::kContentType);
}

}  // namespace

HttpFrontend::HttpFrontend(HttpFrontendConfig config, DaemonMetrics& metrics)
    : config_(std::move(config)), metrics_(metrics) {}

HttpFrontend::~HttpFrontend() {
  stop();
}

void HttpFrontend::start(std::shared_ptr<grpc::Channel> channel) {
  if (!config_.http_listen.empty()) {
    HttpListenerOptions o;
    o.name = "dashboard";
    o.address = config_.http_listen;
    o.tls_cert_file = config_.tls_cert;
    o.tls_key_file = config_.tls_key;
    o.headers = {{"Content-Security-Policy", kContentSecurityPolicy}};
    dashboard_ = std::make_unique<HttpListener>(o, &metrics_);
    auto index = [](const httplib::Request& req, httplib::Response& res) {
      http::answer_asset(req, res, *http::find_static_asset("index.html"));
    };
    dashboard_->get("/", "/", index);
    dashboard_->get("/static/{file}", R"(/static/([A-Za-z0-9_.-]{1,64}))",
                    [](const httplib::Request& req, httplib::Response& res) {
                      const auto* asset = http::find_static_asset(req.matches[1].str());
                      if (asset == nullptr) {
                        set_error(res, 404, "NOT_FOUND", "no such file");
                        return;
                      }
                      http::answer_asset(req, res, *asset);
                    });
    http::add_dashboard_api(*dashboard_, channel);
    // Behind the token here, as everything on this port: the caller must be a user. (The
    // metrics listener serves the same text without one.)
    std::shared_ptr<v1::SimulationService::Stub> stub = v1::SimulationService::NewStub(channel);
    dashboard_->get(
        "/metrics", "/metrics", [this, stub](const httplib::Request& req, httplib::Response& res) {
          auto ctx = http::forwarded_context(req, res, std::chrono::seconds(10));
          if (!ctx) return;
          v1::Caller caller;
          const grpc::Status st = stub->GetCaller(ctx.get(), v1::GetCallerRequest{}, &caller);
          if (!st.ok()) {
            http::answer_status(res, st);
            return;
          }
          answer_metrics(metrics_, res);
        });
    dashboard_->start();
  }
  if (!config_.metrics_listen.empty()) {
    HttpListenerOptions o;
    o.name = "metrics";
    o.address = config_.metrics_listen;
    o.threads = 2;
    o.max_pending = 16;
    metrics_listener_ = std::make_unique<HttpListener>(o, &metrics_);
    metrics_listener_->get(
        "/metrics", "/metrics",
        [this](const httplib::Request&, httplib::Response& res) { answer_metrics(metrics_, res); });
    metrics_listener_->get("/", "/", [](const httplib::Request&, httplib::Response& res) {
      res.set_content("softshockd metrics: GET /metrics (Prometheus text format)\n",
                      "text/plain; charset=utf-8");
    });
    metrics_listener_->start();
  }
}

void HttpFrontend::stop() {
  if (dashboard_) dashboard_->stop();
  if (metrics_listener_) metrics_listener_->stop();
}

int HttpFrontend::dashboard_port() const {
  return dashboard_ ? dashboard_->port() : 0;
}

int HttpFrontend::metrics_port() const {
  return metrics_listener_ ? metrics_listener_->port() : 0;
}

}  // namespace softshock::server
