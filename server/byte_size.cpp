#include "server/byte_size.hpp"

#include <cmath>
#include <cstdio>

namespace softshock::server {

std::string byte_size(double bytes) {
  static constexpr const char* kUnits[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int unit = 0;
  double value = bytes;
  while (unit < 4 && std::abs(value) >= 1024) value /= 1024, ++unit;
  char buf[40];
  // Three significant figures, without an exponent for 1000-1023.
  std::snprintf(buf, sizeof buf, std::abs(value) >= 999.5 ? "%.0f %s" : "%.3g %s", value,
                kUnits[unit]);
  return buf;
}

}  // namespace softshock::server
