#include "server/transport/auth.hpp"

#include <fcntl.h>
#include <grpcpp/server_context.h>
#include <grpcpp/support/status.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
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
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw std::runtime_error("cannot read token file " + path);
  struct stat st {};
  const bool stat_ok = ::fstat(fd, &st) == 0;
  std::string token;
  char buf[4096];
  for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) != 0;) {
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 || token.size() > kMaxTokenFileBytes) {
      ::close(fd);
      throw std::runtime_error("cannot read token file " + path + " (or it is over 64 KiB)");
    }
    token.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  // Checked on the file actually read (fstat), so a swap between check and read cannot help.
  if (!stat_ok || !S_ISREG(st.st_mode)) {
    throw std::runtime_error("token file " + path + " is not a regular file");
  }
  if ((st.st_mode & (S_IROTH | S_IWOTH)) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    throw std::runtime_error("token file " + path + " is accessible to other users (mode " + mode +
                             "); chmod o-rwx it (0600, or 0640 with the daemon's group)");
  }
  const char* ws = " \t\r\n\v\f";
  const auto first = token.find_first_not_of(ws);
  if (first == std::string::npos) throw std::runtime_error("token file " + path + " is empty");
  token = token.substr(first, token.find_last_not_of(ws) - first + 1);
  if (token.size() < kMinTokenBytes) {
    throw std::runtime_error("token file " + path + " holds " + std::to_string(token.size()) +
                             " bytes; a token needs at least " + std::to_string(kMinTokenBytes) +
                             " (e.g. head -c 32 /dev/urandom | base64)");
  }
  return token;
}

}  // namespace softshock::server
