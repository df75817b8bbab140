// The average nodal pressure triangle (Bonet & Burton 1998), its nodal half, with a
// stabilisation of the element-level volume modes it leaves free (docs/model.md, "Element").
//
// Each node owns a third of the area of every element around it; J_a = (current nodal area) /
// (reference nodal area) carries the Tait response, and an element's volumetric stress is the
// mean of its three nodes'. The stored energy sum_a V_a W_vol(J_a) depends on nodal areas only,
// so P1 triangles no longer lock -- but element areas may then checkerboard at fixed nodal areas
// (seen as alternating J at the rim of a soft gel). The stabilisation energy
//   W_stab = sum_e A_e beta kappa (J_e - Jbar_e)^2 / (2 J_e),  Jbar_e = mean of its nodes' J_a,
// penalises only that discrepancy, which is second order in h for a smooth field, so it does not
// lock; it grows without bound as J_e -> 0, so an element cannot be crushed at finite energy
// (continuum.hpp). Its forces, like the nodal pressure's, are element "mean stresses": with
// rho_e = Jbar_e / J_e,
//   s_e = beta kappa (1 - rho_e^2) / 2, less the mean over the element's nodes of
//   q_a = sum_{e around a} A_e beta kappa (1 - rho_e) / (3 V_a),
// so the element kernel needs per node sigma_m(J_a) - q_a and per element s_e: the forces are the
// exact gradient of the stored energy and the energy balance still closes.
#pragma once

#include <cstddef>
#include <vector>

#include "element_kernels.hpp"

namespace softshock {

// Reference nodal areas V_a = sum over the elements around a of A_e / 3.
std::vector<double> reference_nodal_areas(const ElementGeometry& geometry, std::size_t nodes);

// Pass 1 (elements [begin, end)): adds a_e / 3 (current area, from the nodes' position lanes) to
// each of the element's nodes' area and stores J_e = a_e / A_e.
void accumulate_nodal_areas(const ElementGeometry& geometry, const PackedNode* nodes,
                            std::size_t begin, std::size_t end, double* area, double* j_element);

// On a history sample passes 2 and 3 also sum the stored energy whose gradient the kernel's
// forces are, w_nodal (sum_a V_a W_vol(J_a) + sum_e A_e W_stab(J_e, Jbar_e)) (J/m), from the
// values they compute anyway: weight * V_a W_vol(J_a) added to *sum node by node, then weight *
// A_e W_stab element by element, in index order (so one range gives one deterministic sum).
// sum == nullptr: no energy (every other step).
struct StoredEnergySum {
  double weight = 0;  // w_nodal = 1 - element_weight
  double* sum = nullptr;
};

// Pass 2 (nodes [begin, end)): J_a = area / reference_area, the Tait mean stress sigma_m(J_a)
// and the tangent bulk modulus K(J_a) (both Pa).
void nodal_tait_state(double kappa, double tait_n, const double* reference_area, const double* area,
                      std::size_t begin, std::size_t end, double* nodal_j, double* mean_stress,
                      double* bulk_modulus, StoredEnergySum energy = {});

// Pass 3 (elements [begin, end)): s_e = beta_kappa (1 - rho_e^2) / 2, and
// A_e beta_kappa (1 - rho_e) / 3 added to each of the element's nodes' q_sum.
void accumulate_stabilization(const ElementGeometry& geometry, double beta_kappa,
                              const double* nodal_j, const double* j_element, std::size_t begin,
                              std::size_t end, double* s_element, double* q_sum,
                              StoredEnergySum energy = {});

// Pass 4 (nodes [begin, end)): mean_stress -= q_sum / reference_area, the nodal stress the
// element kernel averages, written with bulk_modulus into the nodes' rows (as pack_nodal_state
// does; one pass over the nodes, not two).
void subtract_stabilization(const double* __restrict reference_area, const double* __restrict q_sum,
                            const double* __restrict bulk_modulus, std::size_t begin,
                            std::size_t end, double* __restrict mean_stress,
                            PackedNode* __restrict nodes);

// All four passes at once, for diagnostics (not the hot path): per element, the volumetric mean
// stress the kernel applies (nodal mean + stabilisation; element_weight blends in the element's
// own sigma_m(J_e)), and the stored volumetric + stabilisation energy of the body (J/m).
struct NodalPressureState {
  std::vector<double> element_mean_stress;
  double stored_energy = 0;
};
NodalPressureState nodal_pressure_state(const ElementGeometry& geometry,
                                        const std::vector<double>& reference_area, double kappa,
                                        double tait_n, double element_weight, double beta,
                                        const double* x, const double* y);

}  // namespace softshock
