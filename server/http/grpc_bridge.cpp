#include "server/http/grpc_bridge.hpp"

#include <google/protobuf/util/json_util.h>
#include <httplib.h>

#include <charconv>
#include <cmath>
#include <string_view>

#include "server/http/http_listener.hpp"
#include "server/transport/rpc_guard.hpp"

namespace softshock::server::http {

namespace {

constexpr std::size_t kMaxAuthorizationBytes = 4096;

bool printable_ascii(std::string_view s) {
  for (char c : s) {
    if (c < 0x21 || c > 0x7e) return false;
  }
  return true;
}

}  // namespace

int http_status(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK:
      return 200;
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::OUT_OF_RANGE:
      return 400;
    case grpc::StatusCode::UNAUTHENTICATED:
      return 401;
    case grpc::StatusCode::PERMISSION_DENIED:
      return 403;
    case grpc::StatusCode::NOT_FOUND:
      return 404;
    case grpc::StatusCode::ALREADY_EXISTS:
    case grpc::StatusCode::FAILED_PRECONDITION:
    case grpc::StatusCode::ABORTED:
      return 409;
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return 429;
    case grpc::StatusCode::UNIMPLEMENTED:
      return 501;
    case grpc::StatusCode::UNAVAILABLE:
      return 503;
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return 504;
    default:
      return 500;
  }
}

void answer_status(httplib::Response& res, const grpc::Status& status) {
  set_error(res, http_status(status.error_code()), rpc::status_code_name(status.error_code()),
            status.error_message());
  if (status.error_code() == grpc::StatusCode::UNAUTHENTICATED) {
    res.set_header("WWW-Authenticate", "Bearer realm=\"softshock\"");
  }
}

void answer_message(httplib::Response& res, const google::protobuf::Message& message) {
  google::protobuf::util::JsonPrintOptions options;
  options.always_print_primitive_fields = true;
  options.preserve_proto_field_names = true;
  std::string json;
  const auto status = google::protobuf::util::MessageToJsonString(message, &json, options);
  if (!status.ok()) {
    set_error(res, 500, "INTERNAL", "cannot write the answer as JSON: " + status.ToString());
    return;
  }
  res.status = 200;
  res.set_header("Cache-Control", "no-store");
  res.set_content(json, "application/json");
}

std::unique_ptr<grpc::ClientContext> forwarded_context(const httplib::Request& req,
                                                       httplib::Response& res,
                                                       std::chrono::seconds deadline) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->set_deadline(std::chrono::system_clock::now() + deadline);
  if (!req.has_header("Authorization")) return ctx;  // the service decides (auth off: allowed)
  const std::string value = req.get_header_value("Authorization");
  static constexpr std::string_view kScheme = "Bearer ";
  const std::string_view token =
      std::string_view(value).substr(std::min(value.size(), kScheme.size()));
  if (value.size() > kMaxAuthorizationBytes || value.compare(0, kScheme.size(), kScheme) != 0 ||
      token.empty() || !printable_ascii(token) || req.get_header_value_count("Authorization") > 1) {
    answer_status(res, {grpc::StatusCode::UNAUTHENTICATED,
                        "the Authorization header must be one 'Bearer <token>'"});
    return nullptr;
  }
  ctx->AddMetadata("authorization", value);
  return ctx;
}

int int_param(const httplib::Request& req, const std::string& name, int fallback, int lo, int hi) {
  const std::string v = req.get_param_value(name);
  if (v.empty()) return fallback;
  int x = 0;
  const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  if (ec != std::errc() || ptr != v.data() + v.size() || x < lo || x > hi) {
    throw BadParameter(name + " must be an integer in " + std::to_string(lo) + ".." +
                       std::to_string(hi));
  }
  return x;
}

std::optional<double> double_param(const httplib::Request& req, const std::string& name) {
  const std::string v = req.get_param_value(name);
  if (v.empty()) return std::nullopt;
  double x = 0;
  const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  if (ec != std::errc() || ptr != v.data() + v.size() || !std::isfinite(x)) {
    throw BadParameter(name + " must be a finite number");
  }
  return x;
}

std::string string_param(const httplib::Request& req, const std::string& name,
                         std::size_t max_bytes) {
  std::string v = req.get_param_value(name);
  if (v.size() > max_bytes) {
    throw BadParameter(name + " must be at most " + std::to_string(max_bytes) + " bytes");
  }
  return v;
}

}  // namespace softshock::server::http
