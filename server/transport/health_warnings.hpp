// Warnings about how the daemon is set up (a bearer token served without TLS off loopback),
// carried by every grpc.health.v1.Health answer: the standard HealthCheckResponse has only a
// status, so each warning travels as one `softshock-warning` entry of the answer's initial
// metadata. Probes (Kubernetes, the image's HEALTHCHECK) ignore it; `softshock health` and the
// Python client's health_warnings() show it.
#pragma once

#include <grpcpp/support/server_interceptor.h>

#include <memory>
#include <string>
#include <vector>

namespace softshock::server {

inline constexpr const char* kHealthWarningKey = "softshock-warning";

// The interceptor factory for ServerBuilder::experimental().SetInterceptorCreators(); calls to
// other services are not intercepted at all.
std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface> health_warnings(
    std::vector<std::string> warnings);

}  // namespace softshock::server
