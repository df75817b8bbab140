#include "server/auth.hpp"

#include <grpcpp/server_context.h>
#include <grpcpp/support/status.h>

#include <fstream>
#include <sstream>
#include <stdexcept>

namespace softshock::server {

bool constant_time_equal(const std::string& a, const std::string& b) {
  // Runs over the longer length; a length difference only shows in the result.
  const std::size_t n = std::max(a.size(), b.size());
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char ca = i < a.size() ? static_cast<unsigned char>(a[i]) : 0;
    const unsigned char cb = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
    diff |= static_cast<unsigned char>(ca ^ cb);
  }
  return diff == 0;
}

grpc::Status Authenticator::check(const grpc::ServerContext& context) const {
  if (!enabled()) return grpc::Status::OK;
  const auto& metadata = context.client_metadata();
  auto it = metadata.find("authorization");
  if (it == metadata.end()) {
    return {grpc::StatusCode::UNAUTHENTICATED, "missing 'authorization: Bearer <token>' metadata"};
  }
  const std::string value(it->second.data(), it->second.size());
  static constexpr std::string_view kScheme = "Bearer ";
  if (value.size() < kScheme.size() || value.compare(0, kScheme.size(), kScheme) != 0) {
    return {grpc::StatusCode::UNAUTHENTICATED, "authorization must be 'Bearer <token>'"};
  }
  if (!constant_time_equal(value.substr(kScheme.size()), token_)) {
    return {grpc::StatusCode::UNAUTHENTICATED, "invalid token"};
  }
  return grpc::Status::OK;
}

std::string read_token_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read token file " + path);
  std::ostringstream s;
  s << in.rdbuf();
  std::string token = s.str();
  const char* ws = " \t\r\n\v\f";
  const auto first = token.find_first_not_of(ws);
  if (first == std::string::npos) throw std::runtime_error("token file " + path + " is empty");
  token = token.substr(first, token.find_last_not_of(ws) - first + 1);
  return token;
}

}  // namespace softshock::server
