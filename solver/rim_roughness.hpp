// A random but repeatable roughness of the rim, so that an unseeded run is seeded by a known
// physical perturbation rather than by the mesh (docs/model.md, "Seeded perturbations").
#pragma once

#include <array>
#include <cstdint>

#include "mesh.hpp"

namespace softshock {

struct RimRoughness {
  double amplitude = 0.0;  // rms of delta(theta), as a fraction of R0
  int min_mode = 2, max_mode = 64;
  uint64_t seed = 1;
};

// delta(theta) = c sum_{m = min..max} cos(m theta + phi_m), c = amplitude sqrt(2 / count), the
// phases phi_m uniform in [0, 2 pi) from SplitMix64(seed, m): the same on every platform.
double rim_roughness_delta(const RimRoughness& roughness, double theta);

// Moves every node radially about the origin, r -> r (1 + delta(theta) (r / R0)^2): the rim
// (r = R0) by delta, the interior smoothly less, so no element near the rim is distorted.
void apply_rim_roughness(Mesh& mesh, std::array<double, 2> origin, double r0,
                         const RimRoughness& roughness);

}  // namespace softshock
