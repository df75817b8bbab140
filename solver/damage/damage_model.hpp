// The phase-field damage laws at a point, in the spirit of continuum.hpp: small inline functions
// shared by the damage pass (damage_pass.cpp), its solver and the tests, so the physics is written
// once (docs/model.md, "Damage").
//
// Both models are one equation in the damage d in [0, 1] (model 2's integrity c = 1 - d):
//   zeta dd/dt + (s + 2H) d - s l^2 Lap d = 2H,
// with the stress degraded by g(d) = (1 - d)^2 (model 2: c^2, the same function) and
//   model 1 (Talamini, Mao & Anand 2018): s = eps_f, l the length, H = max_t <psi+ - eps_f/2>,
//     zeta the damage viscosity; the crack's energy G_c = eps_f l for zeta -> 0;
//   model 2 (Giovanardi, Scotti & Formaggia 2017; Ambrosio-Tortorelli AT2): s = G / eps,
//     l = eps, H = max_t psi+, zeta = 0 (an elliptic equation); G_c = G.
// psi+ is the tension-only driving energy density (per reference volume): the deviatoric
// (neo-Hookean) energy plus the volumetric (Tait) energy where J > 1 only. The 2 GPa shock
// compresses the gel to J ~ 0.75 and stores ~160 MJ/m^3 of volumetric energy, against s ~ 2 MPa:
// a total-energy driver would break the gel in compression, so compressive pressure neither
// drives damage nor is degraded.
#pragma once

#include <cmath>

#include "solver/model.hpp"

namespace softshock::damage {

// The coefficients of the one equation above for either model.
struct Coefficients {
  double s_Pa = 0;          // eps_f or G / eps: the local resistance (Pa = J/m^3)
  double length_m = 0;      // l or eps
  double threshold_Pa = 0;  // psi+ below it drives nothing: eps_f / 2 or 0
  double zeta_Pa_s = 0;     // the damage viscosity (model 2: 0)
  // s l^2: the gradient term's coefficient (N, per unit of |grad d|^2).
  double gradient_N() const { return s_Pa * length_m * length_m; }
  // The energy of a fully formed straight crack per unit area: s l (model 1's eps_f l, model
  // 2's G).
  double fracture_energy_J_m2() const { return s_Pa * length_m; }
};

inline Coefficients coefficients(const Damage& p) {
  if (p.model == DamageModel::kTalamini)
    return {p.epsilon_f_Pa, p.length_m, 0.5 * p.epsilon_f_Pa, p.zeta_Pa_s};
  if (p.model == DamageModel::kGiovanardi)
    return {p.fracture_energy_J_m2 / p.length_m, p.length_m, 0.0, 0.0};
  return {};
}

// The degradation of the deviatoric and tensile volumetric stress, g(d) = (1 - d)^2.
inline double degradation(double d) {
  return (1.0 - d) * (1.0 - d);
}

// The tensile part of the volumetric energy: W_vol(J) where J > 1, else 0 (the Tait energy is
// >= 0 on both sides of J = 1; only the side that opens the gel drives damage).
inline double tensile_volumetric_energy(double w_vol, double j) {
  return j > 1.0 ? w_vol : 0.0;
}

// The degraded mean stress: tension (sigma_m > 0, i.e. J > 1) times g, compression as it is.
inline double degraded_mean_stress(double mean_stress, double g) {
  return mean_stress > 0.0 ? g * mean_stress : mean_stress;
}

// The driving energy of one update: <psi+ - threshold>; H is its largest value so far.
inline double driving_energy(double psi_plus, double threshold) {
  return psi_plus > threshold ? psi_plus - threshold : 0.0;
}

// The homogeneous, rate-independent solution (no gradient, zeta -> 0): d = 2H / (2H + s).
// Model 2 with psi = E e^2 / 2: d = E e^2 / (E e^2 + G / eps); model 1: d = 1 - eps_f / (2 psi)
// once psi > eps_f / 2.
inline double homogeneous_damage(double h, double s) {
  return 2.0 * h / (2.0 * h + s);
}

// The damage ODE at a point under a constant H from d(0) = 0: zeta dd/dt + (s + 2H) d = 2H gives
// d = d_inf (1 - exp(-(2H + s) t / zeta)), d_inf = 2H / (2H + s).
inline double point_damage(double h, double s, double zeta, double t) {
  return homogeneous_damage(h, s) * (1.0 - std::exp(-(2.0 * h + s) * t / zeta));
}

// One backward Euler step of that ODE: (zeta / dt)(d+ - d) + (s + 2H) d+ = 2H.
inline double point_damage_step(double d, double h, double s, double zeta, double dt) {
  const double rate = zeta / dt;
  return (rate * d + 2.0 * h) / (rate + s + 2.0 * h);
}

// The regularised crack's energy density s/2 (d^2 + l^2 |grad d|^2) (J/m^3): model 1's
// eps_f/2 (d^2 + l^2 |grad d|^2), model 2's G ((1 - c)^2 / (2 eps) + eps |grad c|^2 / 2).
inline double crack_energy_density(const Coefficients& c, double d, double grad_d_sq) {
  return 0.5 * c.s_Pa * (d * d + c.length_m * c.length_m * grad_d_sq);
}

}  // namespace softshock::damage
