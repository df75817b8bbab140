// The one wrapper every RPC handler runs behind: the token check, then the handler, with every
// exception turned into a status (and a log line) so a bug in one request never takes the
// daemon down. A SpecError is the client's (INVALID_ARGUMENT), a ResourceExhausted a bound that
// was reached (RESOURCE_EXHAUSTED), a CatalogueError the store's (UNAVAILABLE: retry), anything
// else INTERNAL.
#pragma once

#include <grpcpp/grpcpp.h>

#include <exception>
#include <string>

#include "server/log.hpp"
#include "server/store/catalogue.hpp"
#include "server/store/resource_exhausted.hpp"
#include "server/transport/auth.hpp"
#include "solver/run_spec.hpp"

namespace softshock::server {

template <typename F>
grpc::Status guarded(const Authenticator& auth, const grpc::ServerContext* ctx, const char* rpc,
                     F&& body) {
  if (grpc::Status s = auth.check(*ctx); !s.ok()) return s;
  try {
    return body();
  } catch (const SpecError& e) {
    return {grpc::StatusCode::INVALID_ARGUMENT, e.what()};
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

}  // namespace softshock::server
