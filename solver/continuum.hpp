// The constitutive law and element kinematics as small inline functions, shared by the element
// kernels (hot loops) and the diagnostics so the physics is written once. Tensors are templated
// on the dimension (deal.II's `template <int dim>`): Tensor<2> is the plane-strain in-plane block
// {xx, xy, yx, yy} (F_zz = 1, no out-of-plane coupling), Tensor<3> the full 3x3 {xx, xy, xz, yx,
// yy, yz, zx, zy, zz}, both row-major. The scalar laws (Tait, neo-Hookean, viscosities, stable
// step) are the same in both.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>

namespace softshock::continuum {

template <int dim>
using Tensor = std::array<double, dim * dim>;
using Mat2 = Tensor<2>;
using Mat3 = Tensor<3>;

// The 3-D helpers are large enough that GCC would call rather than inline them, and a call in the
// element loop stops it vectorising: inlined always.
#define SOFTSHOCK_ALWAYS_INLINE inline __attribute__((always_inline))

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

// The element loop's five quotients from one division: 1/J, 1/length^2 (the smallest altitude),
// 1/(J + J_prev) (ln(J / J_prev)), 1/(J_prev dt) (the velocity gradient) and 1/(dt c^2). Each is
// 1/(product of all five) times the other four: a few ulp, and (SI units; the product ~1e-26 at
// 16.5k triangles) far from under- or overflow for any mesh above a nanometre. T is double or a
// GCC vector of doubles (one element per lane).
template <class T>
struct StepReciprocals {
  T j, length_sq, j_sum, j_prev_dt, dt_c_sq;
};
template <class T>
SOFTSHOCK_ALWAYS_INLINE StepReciprocals<T> step_reciprocals(T j, T length_sq, T j_prev, double dt,
                                                            T c_sq) {
  const T den_u = j + j_prev, den_v = j_prev * dt, den_z = dt * c_sq;
  const T p_a = j * length_sq, p_b = den_u * den_v;
  const T ab = p_a * p_b, ac = p_a * den_z, bc = p_b * den_z;
  const T r = 1.0 / (ab * den_z);
  return {r * bc * length_sq, r * bc * j, r * ac * den_v, r * ac * den_u, r * ab};
}

// ---- 3-D kinematics (Tet4) -------------------------------------------------------------
// Templated on the scalar T: double, or a GCC vector of doubles, one element per lane (the tet
// element loop, tet4_kernels.cpp); the same expressions either way.
template <class T>
using Mat3Of = std::array<T, 9>;

// F = Ds Dm^-1, Ds's columns the current edges e1, e2, e3 (from node 0), Dm^-1 precomputed.
template <class T>
SOFTSHOCK_ALWAYS_INLINE Mat3Of<T> deformation_gradient(T e1x, T e1y, T e1z, T e2x, T e2y, T e2z,
                                                       T e3x, T e3y, T e3z,
                                                       const Mat3Of<T>& dm_inv) {
  const T* m = dm_inv.data();
  return {e1x * m[0] + e2x * m[3] + e3x * m[6], e1x * m[1] + e2x * m[4] + e3x * m[7],
          e1x * m[2] + e2x * m[5] + e3x * m[8], e1y * m[0] + e2y * m[3] + e3y * m[6],
          e1y * m[1] + e2y * m[4] + e3y * m[7], e1y * m[2] + e2y * m[5] + e3y * m[8],
          e1z * m[0] + e2z * m[3] + e3z * m[6], e1z * m[1] + e2z * m[4] + e3z * m[7],
          e1z * m[2] + e2z * m[5] + e3z * m[8]};
}

// Cofactor J F^-T: row i, column j is (-1)^(i+j) times the minor of F_ij.
template <class T>
SOFTSHOCK_ALWAYS_INLINE Mat3Of<T> cofactor(const Mat3Of<T>& f) {
  return {f[4] * f[8] - f[5] * f[7], f[5] * f[6] - f[3] * f[8], f[3] * f[7] - f[4] * f[6],
          f[2] * f[7] - f[1] * f[8], f[0] * f[8] - f[2] * f[6], f[1] * f[6] - f[0] * f[7],
          f[1] * f[5] - f[2] * f[4], f[2] * f[3] - f[0] * f[5], f[0] * f[4] - f[1] * f[3]};
}

// det F from F and its cofactor (expansion along the first row).
template <class T>
SOFTSHOCK_ALWAYS_INLINE T det(const Mat3Of<T>& f, const Mat3Of<T>& cof) {
  return f[0] * cof[0] + f[1] * cof[1] + f[2] * cof[2];
}
template <class T>
SOFTSHOCK_ALWAYS_INLINE T det(const Mat3Of<T>& f) {
  return det(f, cofactor(f));
}

// I1 = tr(F^T F).
template <class T>
SOFTSHOCK_ALWAYS_INLINE T first_invariant(const Mat3Of<T>& f) {
  T sum{};
  for (const T& v : f) sum += v * v;
  return sum;
}

// ---- the material ----------------------------------------------------------------------

// Neo-Hookean deviatoric energy mu/2 (I1 J^-2/3 - 3).
inline double neo_hookean_energy(double mu, double i1, double j_pow_minus_two_thirds) {
  return 0.5 * mu * (i1 * j_pow_minus_two_thirds - 3.0);
}

inline constexpr double kThird = 1.0 / 3.0;

// Elastic first Piola-Kirchhoff stress (2-D: the in-plane block):
// P = sigma_m cof(F) + mu J^-2/3 (F - I1/3 F^-T), with F^-T = cof(F) / J; takes 1 / J (the kernel
// computes it once for every term that divides by J).
// (N = dim * dim: Mat2 or Mat3, deduced.)
template <std::size_t N>
inline std::array<double, N> elastic_piola_inv_j(const std::array<double, N>& f,
                                                 const std::array<double, N>& cof, double inv_j,
                                                 double mean_stress, double mu,
                                                 double j_pow_minus_two_thirds) {
  const double a = mu * j_pow_minus_two_thirds;
  const double s = mean_stress - a * first_invariant(f) * (kThird * inv_j);
  std::array<double, N> p;
  for (std::size_t k = 0; k < N; ++k) p[k] = s * cof[k] + a * f[k];
  return p;
}
template <std::size_t N>
inline std::array<double, N> elastic_piola(const std::array<double, N>& f,
                                           const std::array<double, N>& cof, double j,
                                           double mean_stress, double mu,
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

// The same in 3-D, the full 3x3 deviator: l = ((F - F_prev) / dt) F_prev^-1 with F_prev^-1 =
// cof(F_prev)^T / J_prev, d = sym(l), sigma_v = 2 nu (d - tr(d)/3 I) + zeta tr(d) I, P_v =
// sigma_v cof(F). Takes cof_prev = cof(F_prev) and inv = 1 / (J_prev dt).
template <class T>
SOFTSHOCK_ALWAYS_INLINE Mat3Of<T> viscous_piola_inv(const Mat3Of<T>& f, const Mat3Of<T>& f_prev,
                                                    const Mat3Of<T>& cof_prev, const Mat3Of<T>& cof,
                                                    T nu, T zeta, T inv) {
  Mat3Of<T> df;
  for (int k = 0; k < 9; ++k) df[k] = f[k] - f_prev[k];
  // l_ij = sum_k dF_ik (F_prev^-1)_kj = sum_k dF_ik cof_prev_jk / (J_prev dt)
  Mat3Of<T> l;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      l[3 * i + j] = (df[3 * i] * cof_prev[3 * j] + df[3 * i + 1] * cof_prev[3 * j + 1] +
                      df[3 * i + 2] * cof_prev[3 * j + 2]) *
                     inv;
  const T trace = l[0] + l[4] + l[8];
  const T diagonal = zeta * trace - 2.0 * nu * kThird * trace;
  const T s00 = 2.0 * nu * l[0] + diagonal, s11 = 2.0 * nu * l[4] + diagonal,
          s22 = 2.0 * nu * l[8] + diagonal;
  const T s01 = nu * (l[1] + l[3]), s02 = nu * (l[2] + l[6]), s12 = nu * (l[5] + l[7]);
  return {s00 * cof[0] + s01 * cof[3] + s02 * cof[6], s00 * cof[1] + s01 * cof[4] + s02 * cof[7],
          s00 * cof[2] + s01 * cof[5] + s02 * cof[8], s01 * cof[0] + s11 * cof[3] + s12 * cof[6],
          s01 * cof[1] + s11 * cof[4] + s12 * cof[7], s01 * cof[2] + s11 * cof[5] + s12 * cof[8],
          s02 * cof[0] + s12 * cof[3] + s22 * cof[6], s02 * cof[1] + s12 * cof[4] + s22 * cof[7],
          s02 * cof[2] + s12 * cof[5] + s22 * cof[8]};
}
inline Mat3 viscous_piola(const Mat3& f, const Mat3& f_prev, const Mat3& cof, double nu,
                          double zeta, double dt) {
  const Mat3 cof_prev = cofactor(f_prev);
  return viscous_piola_inv(f, f_prev, cof_prev, cof, nu, zeta, 1.0 / (det(f_prev, cof_prev) * dt));
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

// Aspect ratio of the current triangle: longest edge^2 / (2 area) (equilateral: 2/sqrt(3)), which
// is the longest edge over the smallest altitude.
inline double aspect_ratio(double e1x, double e1y, double e2x, double e2y) {
  return longest_edge_sq(e1x, e1y, e2x, e2y) / (e1x * e2y - e1y * e2x);
}

// ---- 3-D element lengths (Tet4) ----------------------------------------------------------

// The largest of the squared face-area vectors (times 2) of the tetrahedron with edges e1, e2, e3
// from node 0: |e1 x e2|^2, |e2 x e3|^2, |e3 x e1|^2, |(e2 - e1) x (e3 - e1)|^2.
template <class T>
SOFTSHOCK_ALWAYS_INLINE T largest_face_sq(T e1x, T e1y, T e1z, T e2x, T e2y, T e2z, T e3x, T e3y,
                                          T e3z) {
  auto cross_sq = [](T ax, T ay, T az, T bx, T by, T bz) {
    const T cx = ay * bz - az * by, cy = az * bx - ax * bz, cz = ax * by - ay * bx;
    return cx * cx + cy * cy + cz * cz;
  };
  const T a = cross_sq(e1x, e1y, e1z, e2x, e2y, e2z);
  const T b = cross_sq(e2x, e2y, e2z, e3x, e3y, e3z);
  const T c = cross_sq(e3x, e3y, e3z, e1x, e1y, e1z);
  const T d = cross_sq(e2x - e1x, e2y - e1y, e2z - e1z, e3x - e1x, e3y - e1y, e3z - e1z);
  const T ab = a > b ? a : b, cd = c > d ? c : d;  // no fmax: keeps the loop vectorised
  return ab > cd ? ab : cd;
}
// The largest squared edge length of the tetrahedron (six edges).
template <class T>
SOFTSHOCK_ALWAYS_INLINE T longest_edge_sq(T e1x, T e1y, T e1z, T e2x, T e2y, T e2z, T e3x, T e3y,
                                          T e3z) {
  auto sq = [](T x, T y, T z) { return x * x + y * y + z * z; };
  const T a = sq(e1x, e1y, e1z), b = sq(e2x, e2y, e2z), c = sq(e3x, e3y, e3z);
  const T d = sq(e2x - e1x, e2y - e1y, e2z - e1z), e = sq(e3x - e2x, e3y - e2y, e3z - e2z),
          f = sq(e1x - e3x, e1y - e3y, e1z - e3z);
  const T ab = a > b ? a : b, cd = c > d ? c : d, ef = e > f ? e : f;
  const T abcd = ab > cd ? ab : cd;
  return abcd > ef ? abcd : ef;
}
// Smallest altitude squared of a tetrahedron: (3 V / largest face area)^2 = (6 V)^2 / largest
// |cross|^2, 6 V = det[e1 e2 e3].
SOFTSHOCK_ALWAYS_INLINE double smallest_altitude_sq(double six_volume, double largest_face_sq) {
  return six_volume * six_volume / largest_face_sq;
}
// Aspect ratio of a tetrahedron, the longest edge over the smallest altitude (regular:
// sqrt(3/2) = 1.2247), as for triangles.
SOFTSHOCK_ALWAYS_INLINE double aspect_ratio(double longest_edge_sq, double six_volume,
                                            double largest_face_sq) {
  return std::sqrt(longest_edge_sq * largest_face_sq) / six_volume;
}
// The altitude of the regular tetrahedron of volume V, sqrt(2/3) (6 sqrt(2) V)^(1/3): the
// continuous artificial viscosity's length, which an isochoric distortion (a sliver of the same
// volume) leaves unchanged.
inline double regular_tetrahedron_altitude(double volume) {
  return std::sqrt(2.0 / 3.0) * std::cbrt(6.0 * std::sqrt(2.0) * volume);
}

}  // namespace softshock::continuum
