#include "client/connection.hpp"

#include <algorithm>
#include <thread>

namespace softshock::cli {

const char* status_code_name(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK:
      return "OK";
    case grpc::StatusCode::CANCELLED:
      return "CANCELLED";
    case grpc::StatusCode::UNKNOWN:
      return "UNKNOWN";
    case grpc::StatusCode::INVALID_ARGUMENT:
      return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND:
      return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS:
      return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED:
      return "PERMISSION_DENIED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION:
      return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED:
      return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE:
      return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED:
      return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL:
      return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE:
      return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS:
      return "DATA_LOSS";
    case grpc::StatusCode::UNAUTHENTICATED:
      return "UNAUTHENTICATED";
    default:
      return "UNKNOWN_CODE";
  }
}

CliError status_error(const grpc::Status& status, const std::string& target) {
  std::string message = status.error_message();
  if (status.error_code() == grpc::StatusCode::UNAVAILABLE) {
    message = "cannot reach softshockd at " + target + ": " + message;
  } else if (status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED) {
    message = "no answer from " + target + " before the deadline (--timeout)";
  }
  message += std::string(" (") + status_code_name(status.error_code()) + ")";
  // INVALID_ARGUMENT and OUT_OF_RANGE both mean "your request was wrong" (a bad spec, a frame
  // index past the end): the same exit code as a bad command line.
  bool input_error = status.error_code() == grpc::StatusCode::INVALID_ARGUMENT ||
                     status.error_code() == grpc::StatusCode::OUT_OF_RANGE;
  return CliError(input_error ? kExitUsage : kExitFailure, message);
}

Connection::Connection(const GlobalOptions& options)
    : target_(options.server), timeout_s_(options.timeout_s) {
  if (options.token_file) {
    token_ = trim(read_file(*options.token_file));
    if (token_.empty()) usage_error("--token-file " + *options.token_file + " is empty");
  }
  std::shared_ptr<grpc::ChannelCredentials> creds;
  if (options.tls_ca) {
    grpc::SslCredentialsOptions ssl;
    ssl.pem_root_certs = read_file(*options.tls_ca);
    creds = grpc::SslCredentials(ssl);
  } else {
    creds = grpc::InsecureChannelCredentials();
  }
  grpc::ChannelArguments args;
  // Field chunks are well under 1 MiB, but a generous limit keeps a large ListJobs page (full
  // specs per job) from failing on the 4 MiB default.
  args.SetMaxReceiveMessageSize(64 * 1024 * 1024);
  channel_ = grpc::CreateCustomChannel(target_, creds, args);
  service_ = v1::SimulationService::NewStub(channel_);
  meshes_ = v1::MeshService::NewStub(channel_);
  health_ = grpc::health::v1::Health::NewStub(channel_);
}

std::unique_ptr<grpc::ClientContext> Connection::context(bool with_deadline) const {
  auto ctx = std::make_unique<grpc::ClientContext>();
  // Metadata rather than CallCredentials: gRPC refuses call credentials on insecure channels,
  // and the daemon accepts the token on both (loopback deployments often skip TLS).
  if (!token_.empty()) ctx->AddMetadata("authorization", "Bearer " + token_);
  if (with_deadline && timeout_s_ > 0) {
    ctx->set_deadline(std::chrono::system_clock::now() +
                      std::chrono::microseconds(static_cast<int64_t>(timeout_s_ * 1e6)));
  }
  return ctx;
}

void Connection::unary(const std::function<grpc::Status(grpc::ClientContext&)>& call) const {
  using Clock = std::chrono::steady_clock;
  const auto give_up =
      Clock::now() +
      std::chrono::milliseconds(static_cast<int64_t>((timeout_s_ > 0 ? timeout_s_ : 30.0) * 1000));
  // Few, short retries: a daemon restarting under systemd is back within a second or two,
  // and a user typing a wrong --server should not wait long to hear about it.
  constexpr int kMaxAttempts = 4;
  auto backoff = std::chrono::milliseconds(200);
  for (int attempt = 1;; ++attempt) {
    auto ctx = context();
    grpc::Status status = call(*ctx);
    if (status.ok()) return;
    bool retry = status.error_code() == grpc::StatusCode::UNAVAILABLE && attempt < kMaxAttempts &&
                 Clock::now() + backoff < give_up;
    if (!retry) throw status_error(status, target_);
    std::this_thread::sleep_for(backoff);
    backoff = std::min(backoff * 2, std::chrono::milliseconds(2000));
  }
}

}  // namespace softshock::cli
