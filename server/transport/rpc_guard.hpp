// The wrappers every RPC handler runs behind. Both find the caller (transport/auth.hpp: a call
// without one is refused, fail closed), run the handler and turn every exception into a status
// (and a log line) so a bug in one request never takes the daemon down: a SpecError is the
// client's (INVALID_ARGUMENT), a PermissionDenied another user's resource (PERMISSION_DENIED), a
// ResourceExhausted a bound that was reached -- a quota, the disk reserve, a full disk
// (RESOURCE_EXHAUSTED) --, a CatalogueError the store's (UNAVAILABLE: retry), anything else
// INTERNAL. audited() is for the calls that change something: it also writes the audit line
// (policy/audit.hpp) with the outcome.
#pragma once

#include <grpcpp/grpcpp.h>

#include <exception>
#include <functional>
#include <string>
#include <type_traits>

#include "server/log.hpp"
#include "server/policy/audit.hpp"
#include "server/policy/ownership.hpp"
#include "server/store/catalogue.hpp"
#include "server/store/resource_exhausted.hpp"
#include "server/transport/auth.hpp"
#include "solver/run_spec.hpp"

namespace softshock::server {

namespace rpc {

inline grpc::Status run_guarded(const char* rpc, const std::function<grpc::Status()>& body) {
  try {
    return body();
  } catch (const SpecError& e) {
    return {grpc::StatusCode::INVALID_ARGUMENT, e.what()};
  } catch (const PermissionDenied& e) {
    return {grpc::StatusCode::PERMISSION_DENIED, e.what()};
  } catch (const ResourceExhausted& e) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, e.what()};
  } catch (const CatalogueError& e) {
    log_error(rpc, ": catalogue: ", e.what());
    return {grpc::StatusCode::UNAVAILABLE, std::string("catalogue: ") + e.what()};
  } catch (const std::exception& e) {
    log_error(rpc, ": ", e.what());
    return {grpc::StatusCode::INTERNAL, e.what()};
  }
}

inline grpc::Status no_caller() {
  return {grpc::StatusCode::UNAUTHENTICATED, "the call carries no authenticated user"};
}

// The canonical name of a status code, for the audit line.
const char* status_code_name(grpc::StatusCode code);

}  // namespace rpc

// body() or body(const Caller&) -> grpc::Status.
template <typename F>
grpc::Status guarded(const Authenticator& auth, const grpc::ServerContext* ctx, const char* rpc,
                     F&& body) {
  const std::optional<Caller> caller = auth.caller(*ctx);
  if (!caller) return rpc::no_caller();
  return rpc::run_guarded(rpc, [&]() -> grpc::Status {
    if constexpr (std::is_invocable_v<F&, const Caller&>) {
      return body(*caller);
    } else {
      return body();
    }
  });
}

// body(const Caller&, AuditRecord&) -> grpc::Status; the body names the resource in the record.
template <typename F>
grpc::Status audited(const Authenticator& auth, const grpc::ServerContext* ctx, const char* rpc,
                     F&& body) {
  const std::optional<Caller> caller = auth.caller(*ctx);
  if (!caller) return rpc::no_caller();
  AuditRecord record;
  const grpc::Status status = rpc::run_guarded(rpc, [&] { return body(*caller, record); });
  audit(*caller, rpc, record, rpc::status_code_name(status.error_code()), ctx->peer());
  return status;
}

}  // namespace softshock::server
