// How an HTTP request becomes a call of the daemon's own gRPC services and back: the dashboard's
// JSON endpoints (dashboard_api.hpp) are thin adapters that call SimulationService over an
// in-process channel (grpc::Server::InProcessChannel), carrying the request's bearer token as
// the call's `authorization` metadata. So every rule -- who the caller is, what they may cancel,
// page and answer bounds, request validation, the audit line -- is the gRPC service's, applied
// once, the same for the CLI, the Python client and the browser. Here: the token's forwarding,
// gRPC status -> HTTP status, protobuf messages as JSON, and query parameters.
#pragma once

#include <google/protobuf/message.h>
#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

namespace httplib {
struct Request;
struct Response;
}  // namespace httplib

namespace softshock::server::http {

// The HTTP status for a gRPC code: INVALID_ARGUMENT 400, UNAUTHENTICATED 401,
// PERMISSION_DENIED 403, NOT_FOUND 404, ALREADY_EXISTS and FAILED_PRECONDITION 409,
// RESOURCE_EXHAUSTED 429, UNIMPLEMENTED 501, UNAVAILABLE 503, DEADLINE_EXCEEDED 504, others 500.
int http_status(grpc::StatusCode code);

// The answer for a failed call: the HTTP status and {"error": {"code", "message"}}; a 401 also
// carries `WWW-Authenticate: Bearer`.
void answer_status(httplib::Response& res, const grpc::Status& status);
// A message as protobuf's JSON mapping (proto field names, fields at their default values
// included, enums by name, 64-bit integers as strings, NaN as "NaN"); not cached.
void answer_message(httplib::Response& res, const google::protobuf::Message& message);

// A client context for a call made on behalf of `req`: its `Authorization: Bearer <token>` header,
// if any, as the call's metadata, and a deadline. A header that is not a bearer token of
// printable ASCII (at most 4 KiB) answers 401 and returns nullptr. The header never reaches a log.
std::unique_ptr<grpc::ClientContext> forwarded_context(const httplib::Request& req,
                                                       httplib::Response& res,
                                                       std::chrono::seconds deadline);

// A query parameter that is not what it should be: answered 400 by the caller.
class BadParameter : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// Query parameters; an absent or empty one gives the default. Throw BadParameter naming the
// parameter and what it should be.
int int_param(const httplib::Request& req, const std::string& name, int fallback, int lo, int hi);
std::optional<double> double_param(const httplib::Request& req, const std::string& name);
std::string string_param(const httplib::Request& req, const std::string& name,
                         std::size_t max_bytes = 256);

}  // namespace softshock::server::http
