// Model parameters (docs/model.md): Tait + neo-Hookean material, artificial viscosity,
// follower pressure pulse, and the problem a run solves.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "mesh.hpp"

namespace softshock {

struct Material {
  double density_kg_m3 = 1000.0;  // rho0
  double bulk_modulus_Pa = 2e9;   // kappa
  double shear_modulus_Pa = 5e3;  // mu
  double tait_gamma = 6.15;       // gamma-bar; the Tait exponent is n = gamma-bar + 1
  double tait_n() const { return tait_gamma + 1.0; }
};

struct ArtificialViscosity {
  double c1 = 1.0;  // multiplies h * |ln(J+/J)| / dt (compression rate)
  double c2 = 0.1;  // multiplies the acoustic speed
  bool enabled = true;
};

enum class PulseShape { kSquare, kGaussian, kLinear, kQuadratic };

// Pressure history p(t) of the follower load (docs/model.md gives each shape).
struct PressurePulse {
  PulseShape shape = PulseShape::kSquare;
  double pressure_Pa = 2e9;
  double duration_s = 8e-9;
  double at(double t_s) const;  // p(t), Pa
  double end_s() const;         // time after which p == 0
  double impulse_Pa_s() const;  // integral of p over time
};

// Everything a run needs besides the numerical options.
struct Problem {
  Mesh mesh;
  Material material;
  ArtificialViscosity viscosity;
  PressurePulse load;
  // Edges carrying the follower pressure (body on the left); empty = every boundary edge.
  std::vector<std::array<int32_t, 2>> loaded_edges;
  bool load_all_boundary = true;  // false with empty loaded_edges = no load
  // Per-node velocity constraints (sliding walls): empty = free.
  std::vector<uint8_t> fixed_x, fixed_y;
  // Initial velocity per node, m/s: empty = at rest.
  std::vector<double> initial_vx, initial_vy;
  // Polar frame for diagnostics: origin and R0 (normalises A-bar and modes). Negative R0 =
  // derive: origin = area centroid, R0 = mean reference distance of the outer boundary nodes.
  std::array<double, 2> origin{0.0, 0.0};
  double reference_radius_m = -1.0;
  double center_region_radius_m = 5e-6;  // "centre" = elements with centroid this close
};

struct SolverOptions {
  double end_time_s = 800e-9;
  double cfl = 0.5;
  double history_interval_s = 1e-9;
  double output_interval_s = 20e-9;  // <= 0: no field frames
  int modes = 64;                    // Fourier modes 0..modes of the rim radial displacement
  int threads = 1;                   // element-loop threads
  int64_t max_steps = 0;             // 0 = unlimited
};

// Origin and R0 of the diagnostics' polar frame: the Problem's own when reference_radius_m > 0,
// else the area centroid and the mean reference distance of the outer boundary nodes.
struct PolarFrame {
  std::array<double, 2> origin;
  double reference_radius_m;
};
PolarFrame polar_frame(const Problem& problem);

}  // namespace softshock
