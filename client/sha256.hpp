// SHA-256 on the client (OpenSSL's libcrypto, which gRPC already brings): `softshock fetch`
// checks every downloaded file against the digest the daemon sends.
#pragma once

#include <string>
#include <string_view>

struct evp_md_ctx_st;

namespace softshock::cli {

class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void update(std::string_view bytes);
  std::string hex_digest();  // lower-case hex; the object is then spent

 private:
  evp_md_ctx_st* ctx_;
};

// Lower-case hex SHA-256 of a whole file. Throws CliError when it cannot be read.
std::string sha256_of_file(const std::string& path);

}  // namespace softshock::cli
