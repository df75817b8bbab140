// Byte counts in the daemon's messages, one format for all of them: binary units to three
// significant figures ("100 MiB", "1.5 GiB", "20.3 KiB", "512 B"), as the limits are set
// (--max-job-disk 16G is 16 GiB).
#pragma once

#include <concepts>
#include <string>

namespace softshock::server {

std::string byte_size(double bytes);
// Any integer count (file sizes, limits): exact below 2^53 bytes, which is all of them.
template <std::integral Bytes>
std::string byte_size(Bytes bytes) {
  return byte_size(static_cast<double>(bytes));
}

}  // namespace softshock::server
