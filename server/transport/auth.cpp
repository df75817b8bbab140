#include "server/transport/auth.hpp"

#include <grpc/grpc.h>
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server_context.h>

#include <stdexcept>
#include <string_view>

namespace softshock::server {

namespace {

// Calls that need no token: health checks (probes) and server reflection (public schema).
constexpr std::string_view kOpenPrefixes[] = {
    "/grpc.health.v1.Health/",
    "/grpc.reflection.v1alpha.ServerReflection/",
    "/grpc.reflection.v1.ServerReflection/",
};

std::string_view view(const grpc_slice& slice) {
  return {reinterpret_cast<const char*>(GRPC_SLICE_START_PTR(slice)), GRPC_SLICE_LENGTH(slice)};
}

// ServerCredentials over credentials made with gRPC core's API. gRPC 1.51's C++ factory for
// plaintext credentials cannot take an auth metadata processor (it aborts); core's insecure and
// SSL credentials can, and a port is added with them as the C++ ones do.
class CoreServerCredentials final : public grpc::ServerCredentials {
 public:
  explicit CoreServerCredentials(grpc_server_credentials* creds) : creds_(creds) {}
  ~CoreServerCredentials() override { grpc_server_credentials_release(creds_); }
  void SetAuthMetadataProcessor(const std::shared_ptr<grpc::AuthMetadataProcessor>&) override {
    throw std::logic_error("the processor of these credentials is set from gRPC core");
  }

 private:
  int AddPortToServer(const std::string& addr, grpc_server* server) override {
    return grpc_server_add_http2_port(server, addr.c_str(), creds_);
  }
  grpc_server_credentials* creds_;
};

}  // namespace

Authenticator::Authenticator(UserTable users)
    : enabled_(!users.empty()), users_(std::make_shared<const UserTable>(std::move(users))) {}

void Authenticator::replace(UserTable users) {
  if (users.empty() != !enabled_) {
    throw std::invalid_argument(enabled_
                                    ? "the new users would leave nobody able to call; kept "
                                      "the old ones"
                                    : "authentication is off; restart the daemon to turn it on");
  }
  auto fresh = std::make_shared<const UserTable>(std::move(users));
  std::lock_guard lock(mutex_);
  users_ = std::move(fresh);
}

std::size_t Authenticator::user_count() const {
  std::lock_guard lock(mutex_);
  return users_->size();
}

std::shared_ptr<grpc::ServerCredentials> Authenticator::credentials(
    const std::string& tls_key_pem, const std::string& tls_cert_pem) {
  grpc_server_credentials* creds = nullptr;
  if (tls_key_pem.empty() && tls_cert_pem.empty()) {
    creds = grpc_insecure_server_credentials_create();
  } else {
    grpc_ssl_pem_key_cert_pair pair{tls_key_pem.c_str(), tls_cert_pem.c_str()};
    creds = grpc_ssl_server_credentials_create_ex(
        nullptr, &pair, 1, GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE, nullptr);
  }
  if (creds == nullptr) throw std::runtime_error("cannot make the server's credentials");
  if (enabled_) {
    grpc_server_credentials_set_auth_metadata_processor(creds,
                                                        {&Authenticator::process, nullptr, this});
  }
  return std::make_shared<CoreServerCredentials>(creds);
}

std::optional<Caller> Authenticator::resolve(std::string_view authorization,
                                             const char** refusal) const {
  static constexpr std::string_view kScheme = "Bearer ";
  if (authorization.substr(0, kScheme.size()) != kScheme) {
    *refusal = "authorization must be 'Bearer <token>'";
    return std::nullopt;
  }
  std::shared_ptr<const UserTable> users;
  {
    std::lock_guard lock(mutex_);
    users = users_;
  }
  auto caller = users->find(authorization.substr(kScheme.size()));
  if (!caller) *refusal = "invalid token";
  return caller;
}

void Authenticator::process(void* state, grpc_auth_context*, const grpc_metadata* md,
                            std::size_t md_count, grpc_process_auth_metadata_done_cb done,
                            void* user_data) {
  auto* self = static_cast<Authenticator*>(state);
  std::string_view path;
  const grpc_metadata* authorization = nullptr;
  int authorizations = 0;
  for (std::size_t i = 0; i < md_count; ++i) {
    const std::string_view key = view(md[i].key);
    if (key == ":path") path = view(md[i].value);
    if (key == "authorization") {
      authorization = &md[i];
      ++authorizations;
    }
  }
  for (std::string_view open : kOpenPrefixes) {
    if (path.substr(0, open.size()) == open) {
      done(user_data, nullptr, 0, nullptr, 0, GRPC_STATUS_OK, nullptr);
      return;
    }
  }
  const char* refusal = nullptr;
  if (authorization == nullptr) {
    refusal = "missing 'authorization: Bearer <token>' metadata";
  } else if (authorizations > 1) {
    refusal = "more than one authorization header";
  } else {
    self->resolve(view(authorization->value), &refusal);
  }
  if (refusal != nullptr) {
    ++self->refused_;
    // What the client sent is not echoed beyond the method's name (bounded, printable).
    log_limited(self->refusal_log_, LogLevel::kWarning,
                "unauthenticated call refused before its request was read: method=" +
                    log_field(path, 120) + " reason=" + log_field(refusal, 80));
    done(user_data, nullptr, 0, nullptr, 0, GRPC_STATUS_UNAUTHENTICATED, refusal);
    return;
  }
  // Nothing is added to `context`: in gRPC 1.51 it is the connection's auth context, shared by
  // every call on the connection, so an identity put there would leak into the next call. The
  // handler finds the caller again from the call's own header (caller() below).
  done(user_data, nullptr, 0, nullptr, 0, GRPC_STATUS_OK, nullptr);
}

std::optional<Caller> Authenticator::caller(const grpc::ServerContext& context) const {
  if (!enabled_) return Caller{kDefaultUser, Role::kAdmin};
  const auto& metadata = context.client_metadata();
  if (metadata.count("authorization") != 1) return std::nullopt;
  const auto value = metadata.find("authorization")->second;
  const char* refusal = nullptr;
  return resolve(std::string_view(value.data(), value.size()), &refusal);
}

}  // namespace softshock::server
