// The channel to softshockd: credentials (insecure or TLS), the bearer token, deadlines, the
// retry policy, and the mapping of gRPC status codes to the CLI's exit codes.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "client/cli_common.hpp"
#include "grpc/health/v1/health.grpc.pb.h"
#include "softshock/v1/service.grpc.pb.h"

namespace softshock::cli {

struct GlobalOptions {
  std::string server = "127.0.0.1:50051";
  std::optional<std::string> token_file;
  std::optional<std::string> tls_ca;
  bool json = false;
  double timeout_s = 30;  // per call; 0 = no deadline
};

const char* status_code_name(grpc::StatusCode code);

// "message (CODE)" with exit code 2 for INVALID_ARGUMENT (the input was wrong) and 1 otherwise.
CliError status_error(const grpc::Status& status, const std::string& target);

class Connection {
 public:
  explicit Connection(const GlobalOptions& options);

  v1::SimulationService::Stub& service() { return *service_; }
  v1::MeshService::Stub& meshes() { return *meshes_; }
  grpc::health::v1::Health::Stub& health() { return *health_; }
  const std::string& target() const { return target_; }
  double timeout_s() const { return timeout_s_; }

  // A fresh context carrying the token; with a deadline when one is configured, unless the
  // call is a watch (a watch may legitimately last as long as the job runs).
  std::unique_ptr<grpc::ClientContext> context(bool with_deadline = true) const;

  // Runs a unary call. UNAVAILABLE is retried with back-off until the call's deadline (AIP-194:
  // it is the one code that means "nothing happened, try again"; submits carry a request_id,
  // so a retry never makes a second job). Any other failure throws status_error().
  void unary(const std::function<grpc::Status(grpc::ClientContext&)>& call) const;

 private:
  std::string target_;
  std::string token_;
  double timeout_s_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::SimulationService::Stub> service_;
  std::unique_ptr<v1::MeshService::Stub> meshes_;
  std::unique_ptr<grpc::health::v1::Health::Stub> health_;
};

}  // namespace softshock::cli
