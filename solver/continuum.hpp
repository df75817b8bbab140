// The constitutive law and element kinematics as small inline functions, shared by the element
// kernel (hot loop) and the diagnostics so the physics is written once. 2x2 in-plane tensors
// are stored row-major as {xx, xy, yx, yy}; plane strain: F_zz = 1.
#pragma once

#include <array>
#include <cmath>

namespace softshock::continuum {

using Mat2 = std::array<double, 4>;

// F = Ds * Dm^-1 with Ds = [x1 - x0, x2 - x0] (current edges), Dm^-1 precomputed.
inline Mat2 deformation_gradient(double e1x, double e1y, double e2x, double e2y,
                                 const Mat2& dm_inv) {
  return {e1x * dm_inv[0] + e2x * dm_inv[2], e1x * dm_inv[1] + e2x * dm_inv[3],
          e1y * dm_inv[0] + e2y * dm_inv[2], e1y * dm_inv[1] + e2y * dm_inv[3]};
}

inline double det(const Mat2& f) {
  return f[0] * f[3] - f[1] * f[2];
}

// Cofactor J F^-T (in-plane block; the zz entry is J).
inline Mat2 cofactor(const Mat2& f) {
  return {f[3], -f[2], -f[1], f[0]};
}

// I1 = tr(F^T F) of the 3x3 plane-strain F (the out-of-plane 1 included).
inline double first_invariant(const Mat2& f) {
  return f[0] * f[0] + f[1] * f[1] + f[2] * f[2] + f[3] * f[3] + 1.0;
}

// Tait mean stress sigma_m(J) = (kappa/n)(1 - J^-n), tension positive; takes J^-n.
inline double tait_mean_stress(double kappa, double n, double j_pow_minus_n) {
  return kappa / n * (1.0 - j_pow_minus_n);
}

// Tait stored energy W_vol = (kappa/n)(J - 1 + (J^(1-n) - 1)/(n - 1)); takes J and J^-n.
inline double tait_energy(double kappa, double n, double j, double j_pow_minus_n) {
  return kappa / n * (j - 1.0 + (j * j_pow_minus_n - 1.0) / (n - 1.0));
}

// Tangent bulk modulus K(J) = kappa J^-n.
inline double tait_bulk_modulus(double kappa, double j_pow_minus_n) {
  return kappa * j_pow_minus_n;
}

// Stabilisation of the average nodal pressure element's element-level volume modes
// (nodal_pressure.hpp, docs/model.md "Element"), per unit reference area:
//   W_stab = beta kappa (J_e - Jbar)^2 / (2 J_e),
// J_e the element's J and Jbar the mean of its nodes' J: the quadratic penalty
// beta kappa (J_e - Jbar)^2 / 2 divided by J_e, so the same where J ~ 1; unlike it, it grows
// without bound as J_e -> 0, so no finite energy crushes an element whose nodes keep their area
// (a strong pulse did that to rim elements with the quadratic form). With rho = Jbar / J_e:
inline double stabilization_energy(double beta_kappa, double j_element, double j_bar) {
  const double discrepancy = j_element - j_bar;
  return 0.5 * beta_kappa * discrepancy * discrepancy / j_element;
}
// dW_stab/dJ_e = beta kappa (1 - rho^2) / 2: the element's mean stress (tension positive).
inline double stabilization_element_stress(double beta_kappa, double rho) {
  return 0.5 * beta_kappa * (1.0 - rho * rho);
}
// -dW_stab/dJbar = beta kappa (1 - rho): what the element passes to its nodes (a third each).
inline double stabilization_nodal_share(double beta_kappa, double rho) {
  return beta_kappa * (1.0 - rho);
}
// Its tangent bulk modulus J_e d(stress)/dJ_e = beta kappa rho^2, from the stress s alone:
// beta kappa - 2 s (beta kappa at rho = 1; it stiffens as the element is crushed).
inline double stabilization_bulk_modulus(double beta_kappa, double element_stress) {
  return beta_kappa - 2.0 * element_stress;
}

// Neo-Hookean deviatoric energy mu/2 (I1 J^-2/3 - 3).
inline double neo_hookean_energy(double mu, double i1, double j_pow_minus_two_thirds) {
  return 0.5 * mu * (i1 * j_pow_minus_two_thirds - 3.0);
}

inline constexpr double kThird = 1.0 / 3.0;

// Elastic first Piola-Kirchhoff stress (in-plane block):
// P = sigma_m cof(F) + mu J^-2/3 (F - I1/3 F^-T), with F^-T = cof(F) / J; takes 1 / J (the kernel
// computes it once for every term that divides by J).
inline Mat2 elastic_piola_inv_j(const Mat2& f, const Mat2& cof, double inv_j, double mean_stress,
                                double mu, double j_pow_minus_two_thirds) {
  const double a = mu * j_pow_minus_two_thirds;
  const double s = mean_stress - a * first_invariant(f) * (kThird * inv_j);
  return {s * cof[0] + a * f[0], s * cof[1] + a * f[1], s * cof[2] + a * f[2],
          s * cof[3] + a * f[3]};
}
inline Mat2 elastic_piola(const Mat2& f, const Mat2& cof, double j, double mean_stress, double mu,
                          double j_pow_minus_two_thirds) {
  return elastic_piola_inv_j(f, cof, 1.0 / j, mean_stress, mu, j_pow_minus_two_thirds);
}

// Squared longitudinal wave speed c^2 = (K + 4 mu / 3) / rho, rho = rho0 / J.
inline double longitudinal_speed_sq(double bulk_modulus, double mu, double rho0, double j) {
  return (bulk_modulus + 4.0 / 3.0 * mu) * j / rho0;
}

// Squared length of the longest edge of the triangle with edges e1, e2 (and e2 - e1).
inline double longest_edge_sq(double e1x, double e1y, double e2x, double e2y) {
  const double l1 = e1x * e1x + e1y * e1y;
  const double l2 = e2x * e2x + e2y * e2y;
  const double l3 = (e2x - e1x) * (e2x - e1x) + (e2y - e1y) * (e2y - e1y);
  // Plain comparisons rather than std::fmax (whose NaN rules become a library call and stop
  // the element loop vectorising); a NaN here belongs to an element flagged as invalid anyway.
  const double l12 = l1 > l2 ? l1 : l2;
  return l12 > l3 ? l12 : l3;
}

// Squared smallest altitude of the current triangle: (2 A)^2 / (longest edge)^2, where
// 2A = e1 x e2 (positive for a valid counter-clockwise element).
inline double smallest_altitude_sq(double e1x, double e1y, double e2x, double e2y) {
  const double twice_area = e1x * e2y - e1y * e2x;
  return twice_area * twice_area / longest_edge_sq(e1x, e1y, e2x, e2y);
}

// Viscous first Piola-Kirchhoff stress P_v = J sigma_v F^-T = sigma_v cof(F), with the Cauchy
// viscous stress sigma_v = 2 nu d_dev + zeta tr(d) I, the lagged velocity gradient
// l = ((F - F_prev) / dt) F_prev^-1, d = sym(l) and the 3x3 deviator (d_zz = 0, so
// d_dev = d - tr(d)/3 I): nu a shear, zeta a bulk viscosity (Pa s). In-plane block only: the zz
// row gives no nodal force in plane strain (sigma_v,zz = zeta tr d - 2 nu tr d / 3).
// Takes inv = 1 / (J_prev dt).
inline Mat2 viscous_piola_inv(const Mat2& f, const Mat2& f_prev, const Mat2& cof, double nu,
                              double zeta, double inv) {
  // F_prev^-1 = cof(F_prev)^T / J_prev
  const double pi00 = f_prev[3], pi01 = -f_prev[1], pi10 = -f_prev[2], pi11 = f_prev[0];
  const double df0 = f[0] - f_prev[0], df1 = f[1] - f_prev[1], df2 = f[2] - f_prev[2],
               df3 = f[3] - f_prev[3];
  const double l00 = (df0 * pi00 + df1 * pi10) * inv;
  const double l01 = (df0 * pi01 + df1 * pi11) * inv;
  const double l10 = (df2 * pi00 + df3 * pi10) * inv;
  const double l11 = (df2 * pi01 + df3 * pi11) * inv;
  const double trace = l00 + l11;
  const double third_trace = trace * kThird;
  const double d00 = 2.0 * nu * (l00 - third_trace) + zeta * trace;
  const double d11 = 2.0 * nu * (l11 - third_trace) + zeta * trace;
  const double d01 = nu * (l01 + l10);
  return {d00 * cof[0] + d01 * cof[2], d00 * cof[1] + d01 * cof[3], d01 * cof[0] + d11 * cof[2],
          d01 * cof[1] + d11 * cof[3]};
}
inline Mat2 viscous_piola(const Mat2& f, const Mat2& f_prev, const Mat2& cof, double nu,
                          double zeta, double dt) {
  return viscous_piola_inv(f, f_prev, cof, nu, zeta, 1.0 / (det(f_prev) * dt));
}

// Out-of-plane Cauchy viscous stress sigma_v,zz = (zeta - 2 nu / 3) tr(d), from the in-plane
// Cauchy components it comes with: sigma_xx + sigma_yy = 2 nu tr d / 3 + 2 zeta tr d.
inline double viscous_zz(double nu, double zeta, double in_plane_trace) {
  const double denominator = 2.0 * nu / 3.0 + 2.0 * zeta;
  return denominator > 0.0 ? (zeta - 2.0 * nu / 3.0) * in_plane_trace / denominator : 0.0;
}

// ln(J / J_prev) without a logarithm: 2 atanh(u) with u = (J - J_prev) / (J + J_prev) (one
// division, and no cancellation between two logarithms), summed to u^9:
// 2u (1 + u^2/3 + u^4/5 + u^6/7 + u^8/9). Every term has u's sign, so the truncation's relative
// error is the tail, at most u^10 / (11 (1 - u^2)):
// <= 1.5e-14 for |J / J_prev - 1| <= 0.1 (|u| <= 0.053), <= 3e-9 for J / J_prev in [0.7, 1.43]
// (|u| <= 0.177), <= 1.7e-6 for J / J_prev in [0.5, 2]. A stable step changes J by
// ~2 CFL |dv| / c (a few per cent, behind a strong shock tens of per cent); the result only
// feeds the artificial viscosity's compression measure z.
inline double log_ratio_u(double u) {  // takes u = (J - J_prev) / (J + J_prev)
  const double u2 = u * u;
  return 2.0 * u *
         (1.0 + u2 * (1.0 / 3.0 + u2 * (1.0 / 5.0 + u2 * (1.0 / 7.0 + u2 * (1.0 / 9.0)))));
}
inline double log_ratio(double j, double j_prev) {
  return log_ratio_u((j - j_prev) / (j + j_prev));
}

// Artificial viscosity nu = 3/4 (h rho0 / J) a (c2 ramp(z) + c1 z+), with the compression
// measure z = -h ln(J / J_prev) / (a dt) (the velocity jump across the element over the sound
// speed) and ramp(z) = min(z+ / z_ramp, 1): continuous in z, so near-isochoric motion (z ~ 0,
// where round-off decides the sign) gets almost none. ramp_inv = 1 / z_ramp; a huge ramp_inv
// gives the thesis's switch (on while compressing). Where z > z_ramp this is the thesis's
// 3/4 (h rho0 / J)(c2 a - c1 h ln(J / J_prev) / dt).
// Takes the current density rho = rho0 / J.
inline double artificial_viscosity_rho(double h, double rho, double c1, double c2,
                                       double acoustic_speed, double z, double ramp_inv) {
  const double z_pos = z > 0.0 ? z : 0.0;
  const double r = z_pos * ramp_inv;
  const double ramp = r < 1.0 ? r : 1.0;
  return 0.75 * h * rho * acoustic_speed * (c2 * ramp + c1 * z_pos);
}
// The same from the product h a alone (the kernel's one square root gives h a, not h and a).
inline double artificial_viscosity_hc(double h_times_speed, double rho, double c1, double c2,
                                      double z, double ramp_inv) {
  const double z_pos = z > 0.0 ? z : 0.0;
  const double r = z_pos * ramp_inv;
  const double ramp = r < 1.0 ? r : 1.0;
  return 0.75 * h_times_speed * rho * (c2 * ramp + c1 * z_pos);
}
inline double artificial_viscosity(double h, double rho0, double j, double c1, double c2,
                                   double acoustic_speed, double z, double ramp_inv) {
  return artificial_viscosity_rho(h, rho0 / j, c1, c2, acoustic_speed, z, ramp_inv);
}

// Squared stable step of one element with viscosity: the central-difference limit for a damped
// oscillator, dt = h / (q + sqrt(q^2 + c^2)), with the viscous speed q = nu_l / (rho h),
// rho = rho0 / J, and the longitudinal viscosity nu_l = 4/3 nu + zeta of a shear viscosity nu
// (2 nu d_dev) and a bulk viscosity zeta. nu_l = 0 gives h^2 / c^2.
// Written without h itself: with Q = q h = nu_l / rho, dt = h^2 / (Q + sqrt(Q^2 + c^2 h^2)) -- one
// square root and one division. kinematic_viscosity = nu_l / rho = nu_l J / rho0 (m^2/s).
inline double stable_step_sq_kinematic(double h_sq, double c_sq, double kinematic_viscosity) {
  const double q = kinematic_viscosity;
  const double dt = h_sq / (q + std::sqrt(q * q + c_sq * h_sq));
  return dt * dt;
}
inline double stable_step_sq(double h_sq, double c_sq, double longitudinal_viscosity, double rho0,
                             double j) {
  return stable_step_sq_kinematic(h_sq, c_sq, longitudinal_viscosity * j / rho0);
}

// Aspect ratio of the current triangle: longest edge^2 / (2 area) (equilateral: 2/sqrt(3)).
inline double aspect_ratio(double e1x, double e1y, double e2x, double e2y) {
  return longest_edge_sq(e1x, e1y, e2x, e2y) / (e1x * e2y - e1y * e2x);
}

}  // namespace softshock::continuum
