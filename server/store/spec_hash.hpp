// SHA-256 (FIPS 180-4) of a canonical spec: the catalogue's spec_hash, so identical parameter
// sets (after defaults are filled) can be found and compared (signac/AiiDA-style dedup).
#pragma once

#include <string>
#include <string_view>

namespace softshock::server {

// Lower-case hex SHA-256 of the bytes.
std::string sha256_hex(std::string_view bytes);

}  // namespace softshock::server
