#include "rim_roughness.hpp"

#include <cmath>
#include <numbers>

namespace softshock {
namespace {

uint64_t splitmix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

double phase(uint64_t seed, int mode) {
  const uint64_t bits = splitmix64(splitmix64(seed) ^ static_cast<uint64_t>(mode));
  return 2.0 * std::numbers::pi * static_cast<double>(bits >> 11) * 0x1.0p-53;
}

}  // namespace

double rim_roughness_delta(const RimRoughness& r, double theta) {
  if (r.amplitude == 0.0 || r.max_mode < r.min_mode) return 0.0;
  const int count = r.max_mode - r.min_mode + 1;
  const double c = r.amplitude * std::sqrt(2.0 / count);
  double delta = 0.0;
  for (int m = r.min_mode; m <= r.max_mode; ++m) delta += std::cos(m * theta + phase(r.seed, m));
  return c * delta;
}

void apply_rim_roughness(Mesh& mesh, std::array<double, 2> origin, double r0,
                         const RimRoughness& roughness) {
  if (roughness.amplitude == 0.0) return;
  for (std::size_t i = 0; i < mesh.node_count(); ++i) {
    const double dx = mesh.x[i] - origin[0], dy = mesh.y[i] - origin[1];
    const double rr = (dx * dx + dy * dy) / (r0 * r0);
    const double s = 1.0 + rim_roughness_delta(roughness, std::atan2(dy, dx)) * rr;
    mesh.x[i] = origin[0] + s * dx, mesh.y[i] = origin[1] + s * dy;
  }
}

}  // namespace softshock
