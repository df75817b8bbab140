#include "ring_mesher.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

namespace softshock {
namespace {

// A pseudo-random fraction in [0, 1) for ring i (SplitMix64): unlike a golden-ratio sequence,
// whose offsets line up along Fibonacci spirals (5, 8, 13 arms), it leaves no angular pattern.
double ring_offset(int i) {
  uint64_t x = static_cast<uint64_t>(i) + 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  x ^= x >> 31;
  return static_cast<double>(x >> 11) * 0x1.0p-53;
}

constexpr int kHexagonalRings = 5;

}  // namespace

Mesh mesh_disk_rings(double radius_m, int target_elements) {
  if (!(radius_m > 0.0) || !std::isfinite(radius_m))
    throw std::invalid_argument("mesh_disk_rings: radius must be positive and finite");
  if (target_elements < 6)
    throw std::invalid_argument("mesh_disk_rings: target_elements must be >= 6, got " +
                                std::to_string(target_elements));
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  // Annulus i holds n_{i-1} + n_i triangles with n_i ~ 2 pi i dr / s = pi sqrt(3) i, so K rings
  // hold ~ pi sqrt(3) K^2 triangles.
  const double per_ring_sq = std::numbers::pi * std::sqrt(3.0);
  const int rings =
      std::max(1, static_cast<int>(std::lround(std::sqrt(target_elements / per_ring_sq))));
  const double dr = radius_m / rings;
  const double spacing = 2.0 * dr / std::sqrt(3.0);

  Mesh mesh;
  mesh.x.push_back(0.0), mesh.y.push_back(0.0);
  std::vector<int32_t> inner{0};       // node indices of the previous ring
  std::vector<double> inner_angle{0};  // their angles, increasing
  for (int i = 1; i <= rings; ++i) {
    const double r = i * dr;
    // The innermost rings continue the hexagon of ring 1 (6 i nodes, one on each of its
    // spokes): the zips of rounded counts there (6 -> 11 -> 16 -> 22 -> 27) hold the mesh's
    // thinnest elements (smallest altitude 0.64 of the median, against >= 0.8 elsewhere) at the
    // centre, where the converging shock focuses and sets the step. Up to ring 5, and within
    // the inner quarter of the radius so that a coarse mesh's rim keeps its random offsets; the
    // spokes lead by 1e-6 of a step so that no zip meets a tie.
    const bool hexagonal = i >= 2 && i <= std::min(kHexagonalRings, rings / 4);
    const int n =
        hexagonal ? 6 * i : std::max(6, static_cast<int>(std::lround(kTwoPi * r / spacing)));
    const double step = kTwoPi / n;
    const double offset = hexagonal ? inner_angle[0] + 1e-6 * step : ring_offset(i) * step;
    std::vector<int32_t> outer(n);
    std::vector<double> outer_angle(n);
    for (int k = 0; k < n; ++k) {
      outer_angle[k] = offset + k * step;
      outer[k] = static_cast<int32_t>(mesh.x.size());
      mesh.x.push_back(r * std::cos(outer_angle[k]));
      mesh.y.push_back(r * std::sin(outer_angle[k]));
    }
    if (inner.size() == 1) {  // the fan around the centre node
      for (int k = 0; k < n; ++k)
        mesh.triangles.push_back({inner[0], outer[k], outer[(k + 1) % n]});
    } else {
      // Zip the two rings by angle: from the pair (inner 0, outer q0 nearest to it), always
      // advance along the ring whose next node comes first, closing one triangle per advance.
      const int m = static_cast<int>(inner.size());
      int q0 = 0;
      double best = kTwoPi;
      for (int k = 0; k < n; ++k) {
        const double d = std::fabs(std::remainder(outer_angle[k] - inner_angle[0], kTwoPi));
        if (d < best) best = d, q0 = k;
      }
      // Unrolled angles: both rings are equally spaced, counted from the starting pair.
      const double inner_step = kTwoPi / m;
      auto inner_at = [&](int p) { return inner_angle[0] + p * inner_step; };
      const double start =
          inner_angle[0] + std::remainder(outer_angle[q0] - inner_angle[0], kTwoPi);
      auto outer_at = [&](int q) { return start + q * step; };
      int p = 0, q = 0;
      while (p < m || q < n) {
        const bool advance_outer = p == m || (q < n && outer_at(q + 1) < inner_at(p + 1));
        const int32_t a = inner[p % m], b = outer[(q0 + q) % n];
        if (advance_outer) {
          mesh.triangles.push_back({a, b, outer[(q0 + q + 1) % n]});
          ++q;
        } else {
          mesh.triangles.push_back({a, b, inner[(p + 1) % m]});
          ++p;
        }
      }
    }
    inner = std::move(outer);
    inner_angle = std::move(outer_angle);
  }
  sort_for_locality(mesh);  // finalizes too (orients every triangle counter-clockwise)
  return mesh;
}

}  // namespace softshock

namespace softshock {

Mesh mesh_cylinder_rings(double radius_m, double thickness_m, int target_elements) {
  if (!(radius_m > 0.0) || !std::isfinite(radius_m) || !(thickness_m > 0.0) ||
      !std::isfinite(thickness_m))
    throw std::invalid_argument("mesh_cylinder_rings: radius and thickness must be positive");
  if (target_elements < 36)
    throw std::invalid_argument("mesh_cylinder_rings: target_elements must be >= 36, got " +
                                std::to_string(target_elements));
  // K rings hold ~ pi sqrt(3) K^2 triangles with node spacing s = 2 R / (sqrt(3) K) along them;
  // layers of height ~ s make prisms of aspect ~1: L = H / s = H K / (s K). With T = 3 L pi
  // sqrt(3) K^2 tetrahedra, K^3 = T (s K) / (3 pi sqrt(3) H). L is then rounded to an even number
  // (the mid-plane is a layer), at least 2, and the triangles per layer follow from T.
  const double per_ring_sq = std::numbers::pi * std::sqrt(3.0);
  const double spacing_per_k = 2.0 * radius_m / std::sqrt(3.0);  // s K
  const double k_cubed = target_elements * spacing_per_k / (3.0 * per_ring_sq * thickness_m);
  const double layers_exact = thickness_m * std::cbrt(k_cubed) / spacing_per_k;
  const int layers = std::max(2, 2 * static_cast<int>(std::lround(0.5 * layers_exact)));
  const int per_layer =
      std::max(6, static_cast<int>(std::lround(target_elements / (3.0 * layers))));
  Mesh mesh = extrude_mesh(mesh_disk_rings(radius_m, per_layer), -0.5 * thickness_m,
                           0.5 * thickness_m, layers);
  sort_for_locality(mesh);
  return mesh;
}

}  // namespace softshock
