// Bearer-token authentication of SimulationService calls: metadata
// `authorization: Bearer <token>`, compared in constant time. Checked at the top of every
// handler (an AuthMetadataProcessor would only work with TLS credentials, and an interceptor
// cannot fail a call with UNAUTHENTICATED in gRPC 1.51). grpc.health.v1 and server reflection
// stay unauthenticated so container probes and tooling work without the secret.
#pragma once

#include <cstddef>
#include <string>

namespace grpc {
class ServerContext;
class Status;
}  // namespace grpc

namespace softshock::server {

class Authenticator {
 public:
  // Empty token = authentication disabled.
  explicit Authenticator(std::string token) : token_(std::move(token)) {}
  bool enabled() const { return !token_.empty(); }
  // OK, or UNAUTHENTICATED (missing/malformed header, or wrong token).
  grpc::Status check(const grpc::ServerContext& context) const;

 private:
  std::string token_;
};

// A guessable token is no protection: at least 32 bytes (e.g. 32 random bytes in base64).
inline constexpr std::size_t kMinTokenBytes = 32;
inline constexpr std::size_t kMaxTokenFileBytes = 64 * 1024;

// Reads the daemon's token file; surrounding whitespace (a trailing newline) is trimmed. Throws
// std::runtime_error if it cannot be read, is not a regular file, is readable or writable by
// other users (mode o+r or o+w), or holds fewer than kMinTokenBytes after trimming.
std::string read_token_file(const std::string& path);

// Compares without an early exit, so timing does not reveal how much of a guess matched.
bool constant_time_equal(const std::string& a, const std::string& b);

}  // namespace softshock::server
