// Bearer-token authentication: every call but health checks and reflection carries the metadata
// `authorization: Bearer <token>`, and the token names a user (server/policy/users.hpp).
//
// Where the check runs: in gRPC's server auth filter, through an auth metadata processor on the
// listening port's credentials. The filter runs when a call's headers arrive, before gRPC
// matches the call to a handler: a call without a valid token ends UNAUTHENTICATED there, its
// request message is never parsed into a protobuf (so neither protobuf's nor our own code logs
// anything about it) and no handler thread is taken. What gRPC does not avoid: the HTTP/2
// transport still receives the bytes the client sent with the call (at most the 4 MiB message
// limit) and drops them. The refusals are logged through a rate limit (20 lines, then one a
// second, with the count of those dropped). The C++ ServerCredentials of gRPC 1.51 allow a
// processor only for TLS; this file makes the credentials from gRPC core instead (plaintext or
// TLS alike), with the processor set on them.
//
// The processor only lets a call through or refuses it: the auth context it is given is, in gRPC
// 1.51, the connection's (shared by every call on it), so nothing per call can be stored there.
// The handler finds the caller again from the call's own header (Authenticator::caller(), the
// same constant-time look-up; a call without a valid one is refused there too: fail closed).
// grpc.health.v1 and server reflection stay open, so container and Kubernetes probes and tooling
// work without a secret.
#pragma once

#include <grpc/grpc_security.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>

#include "server/log.hpp"
#include "server/policy/users.hpp"

namespace grpc {
class ServerContext;
class ServerCredentials;
}  // namespace grpc

namespace softshock::server {

class Authenticator {
 public:
  // An empty table turns authentication off: every call is kDefaultUser, an admin.
  explicit Authenticator(UserTable users = {});
  bool enabled() const { return enabled_; }

  // Credentials to listen with: plaintext, or TLS with the PEM key and certificate chain (both
  // or neither), carrying this authenticator's processor when it is enabled. The authenticator
  // must outlive the server.
  std::shared_ptr<grpc::ServerCredentials> credentials(const std::string& tls_key_pem = "",
                                                       const std::string& tls_cert_pem = "");

  // Replaces the users (a reload); calls that start afterwards see the new table. Throws
  // std::invalid_argument for an empty table while authentication is on (it cannot be turned
  // off while serving) or a non-empty one while it is off.
  void replace(UserTable users);
  std::size_t user_count() const;

  // Who the call runs as: the user its bearer token names; nullopt when authentication is on and
  // the call carries no valid token (then the handler must refuse it: fail closed).
  std::optional<Caller> caller(const grpc::ServerContext& context) const;

  // Calls refused for want of a valid token, since start.
  std::int64_t refused() const { return refused_.load(); }

 private:
  // The caller an authorization header's value names, or nullopt with *refusal saying why.
  std::optional<Caller> resolve(std::string_view authorization, const char** refusal) const;
  static void process(void* state, grpc_auth_context* context, const grpc_metadata* md,
                      std::size_t md_count, grpc_process_auth_metadata_done_cb done,
                      void* user_data);

  bool enabled_;
  mutable std::mutex mutex_;
  std::shared_ptr<const UserTable> users_;
  std::atomic<std::int64_t> refused_{0};
  LogRateLimit refusal_log_{20, 1};
};

}  // namespace softshock::server
