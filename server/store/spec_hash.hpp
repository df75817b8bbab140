// SHA-256 (OpenSSL's libcrypto): the catalogue's spec_hash of a canonical spec, so identical
// parameter sets (after defaults are filled) can be found and compared (signac/AiiDA-style
// dedup), and the id of an uploaded mesh, hashed as its bytes arrive.
#pragma once

#include <string>
#include <string_view>

struct evp_md_ctx_st;  // OpenSSL's EVP_MD_CTX, kept out of this header

namespace softshock::server {

// Lower-case hex SHA-256 of the bytes.
std::string sha256_hex(std::string_view bytes);

// The same over bytes that arrive in parts.
class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void update(std::string_view bytes);
  // Lower-case hex of everything updated so far; the object then starts again, empty.
  std::string hex_digest();

 private:
  evp_md_ctx_st* ctx_;
};

}  // namespace softshock::server
